"""Studies of the envs' numerics: work-precision, convergence orders and invariant drift
against SciPy; gradient checks and gradient accuracy.

The library, one concept per module: `sweeps` (solver settings), `measurements` (what a
study measures of one setting), `reference` (SciPy's solutions), `study` (the
work-precision runner), `verdict` (settings that coincide, resolved timings, the
cheapest), `convergence` (fitted orders), `gradcheck`, `gradient_accuracy`, the
gradient-variance study (`rollout_cost`, `gradient_estimators`, `chaos`,
`gradient_variance`), `figures`, `report` (a study's files and tables) and `recording`,
the one writer of CSV, JSON records and figures, which `benchmarks/` uses too.

Needs the `study` extra (SciPy for the reference; matplotlib for plots; tqdm for the
progress bar): `pip install 'lerax_like[study]'`.
"""

from .convergence import convergence_orders as convergence_orders, fit_order as fit_order
from .gradient_accuracy import (
    GradientStudyConfig as GradientStudyConfig,
    default_gradient_sweeps as default_gradient_sweeps,
    gradient_scenes as gradient_scenes,
    gradient_work_precision as gradient_work_precision,
    run_gradient_study as run_gradient_study,
)
from .reference import (
    dense_reference_trajectories as dense_reference_trajectories,
    reference_trajectories as reference_trajectories,
)
from .recording import (
    environment_record as environment_record,
    fixed_width_table as fixed_width_table,
    matplotlib_available as matplotlib_available,
    pyplot as pyplot,
    write_record as write_record,
)
from .report import (
    CSV_COLUMNS as CSV_COLUMNS,
    GRADIENT_CSV_COLUMNS as GRADIENT_CSV_COLUMNS,
    cheapest_at as cheapest_at,
    format_gradient_table as format_gradient_table,
    format_table as format_table,
    plot_gradient_work_precision as plot_gradient_work_precision,
    plot_work_precision as plot_work_precision,
    read_csv as read_csv,
    write_csv as write_csv,
    write_gradient_study as write_gradient_study,
    write_json as write_json,
    write_study as write_study,
)
from .verdict import group_settings as group_settings, timing_unresolved as timing_unresolved
from .rollout_check import preset_rollouts as preset_rollouts
from .scenes import SCENES as SCENES, make_scene as make_scene, reference_method as reference_method
from .study import (
    SCHEDULES as SCHEDULES,
    SolverSweep as SolverSweep,
    StudyConfig as StudyConfig,
    StudyResult as StudyResult,
    default_sweeps as default_sweeps,
    evaluations_per_step as evaluations_per_step,
    run_study as run_study,
    sweeps_for as sweeps_for,
)

from .._module_attributes import moved_names as _moved_names

# The gradient tools moved to `lerax_like.gradients`; the old imports work and warn.
__getattr__ = _moved_names(__name__, "lerax_like.gradients", ("GradCheckReport", "LeafCheck", "gradcheck", "sensitivity_signs"))
