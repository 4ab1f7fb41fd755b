"""Studies of the envs' numerics against SciPy and against their own gradients.

Three studies, each of one shape: a configuration (a frozen dataclass, checked on
construction), a run (`run_...(config) -> result`) and a result (its `rows` and its
`record`) whose files one function writes (`result.write(out)`), through `recording`:

- `study`: work-precision of the solutions (error against cost per solver setting, with
  convergence orders and invariant drifts): `StudyConfig`, `run_study`, `write_study`;
- `gradient_accuracy`: work-precision of their gradients against the continuous system's:
  `GradientStudyConfig`, `run_gradient_study`, `write_gradient_study`;
- `gradient_variance`: when the simulator's gradients pay (first-order against zeroth-order
  estimators, bias, chaos, float32): `GradientVarianceConfig`, `run_gradient_variance`,
  `write_gradient_variance`.

What they share, one concept per module: `scenes` (scenes by name), `sweeps` (solver
settings), `measurements` (what a study measures of one setting), `reference`,
`hybrid_reference` and `modes_reference` (SciPy's solutions, through impacts and through
any other hybrid system), `verdict` (settings that coincide, resolved timings, the cheapest),
`convergence` (fitted orders), `figures`, `tables` (the terminal tables) and `recording`,
the one writer of CSV, JSON records and figures, which `benchmarks/` uses too. Beside them
`rollout_check` (the presets' rollouts against SciPy) and `gait` (walkers' limit cycles).
The gradient tools the studies use (gradient checks, estimators, sensitivities, Lyapunov
exponents) are in `lerax_like.gradients`.

Needs the `study` extra (SciPy for the reference; matplotlib for plots; tqdm for the
progress bar): `pip install 'lerax_like[study]'`.
"""

from .convergence import convergence_orders as convergence_orders, fit_order as fit_order
from .figures import (
    plot_gradient_variance as plot_gradient_variance,
    plot_gradient_work_precision as plot_gradient_work_precision,
    plot_work_precision as plot_work_precision,
)
from .gradient_accuracy import (
    GRADIENT_CSV_COLUMNS as GRADIENT_CSV_COLUMNS,
    GradientStudyConfig as GradientStudyConfig,
    GradientStudyResult as GradientStudyResult,
    default_gradient_sweeps as default_gradient_sweeps,
    gradient_scenes as gradient_scenes,
    gradient_work_precision as gradient_work_precision,
    run_gradient_study as run_gradient_study,
    write_gradient_study as write_gradient_study,
)
from .gradient_variance import (
    GRADIENT_VARIANCE_CSV_COLUMNS as GRADIENT_VARIANCE_CSV_COLUMNS,
    GradientVarianceConfig as GradientVarianceConfig,
    GradientVarianceResult as GradientVarianceResult,
    run_gradient_variance as run_gradient_variance,
    write_gradient_variance as write_gradient_variance,
)
from .recording import (
    environment_record as environment_record,
    fixed_width_table as fixed_width_table,
    matplotlib_available as matplotlib_available,
    pyplot as pyplot,
    write_record as write_record,
)
from .reference import (
    dense_reference_trajectories as dense_reference_trajectories,
    reference_trajectories as reference_trajectories,
)
from .rollout_check import preset_rollouts as preset_rollouts
from .scenes import SCENES as SCENES, reference_method as reference_method
from .study import (
    CSV_COLUMNS as CSV_COLUMNS,
    SCHEDULES as SCHEDULES,
    VERDICT_TARGETS as VERDICT_TARGETS,
    SolverSweep as SolverSweep,
    StudyConfig as StudyConfig,
    StudyResult as StudyResult,
    default_sweeps as default_sweeps,
    evaluations_per_step as evaluations_per_step,
    read_csv as read_csv,
    run_study as run_study,
    sweeps_for as sweeps_for,
    write_csv as write_csv,
    write_json as write_json,
    write_study as write_study,
)
from .tables import (
    format_gradient_table as format_gradient_table,
    format_gradient_variance_table as format_gradient_variance_table,
    format_orders as format_orders,
    format_table as format_table,
)
from .verdict import (
    cheapest_at as cheapest_at,
    group_settings as group_settings,
    timing_unresolved as timing_unresolved,
)
