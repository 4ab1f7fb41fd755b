"""Work-precision studies: error against cost for every solver setting, on a real scene.

A study takes a scene, a batch of initial states, action schedules, a horizon in env
steps, and solver sweeps (substeps for fixed-step solvers, paired `rtol`/`atol` for
adaptive ones) of any solver: a preset name, a diffrax solver, or a solver registered
with `lerax_like.register_solver`. For each setting it integrates the batch through the
env's own step (`env.evolve` over `[0, dt]` per env step, the input held), and measures

- the error against an independent SciPy reference, at the final time and maximal over
  the env-step ends (max norm over state components and initial states);
- the dense errors, as DiffEqDevTools' `L2` and `Linf`: root mean square and maximum over
  a grid of `dense_points` times per env step (its end included), from the solver's own
  dense output against the reference's (`solve_ivp(dense_output=True)`);
- the run time of the whole batch under `vmap` (compiled first, `block_until_ready`,
  minimum of repeats);
- solver steps and vector-field evaluations, the machine-independent cost;
- for zero input, the drift of the energy (where the scene claims to conserve it) and
  momentum of the dynamics (maximum over the trajectory).

The study's shape, as the other two studies': a `StudyConfig` (frozen, checked), its run
(`run_study(config) -> StudyResult`) and the result (`rows`, `record`), whose files
`write_study` (`result.write`) writes through `recording`, the one writer. The schedules
and SciPy's reference of each are in `_schedules`; the settings are `SolverSweep`s
(`analysis.sweeps`), the measurements of one setting are in `analysis.measurements`, what
the rows conclude (settings that coincide, the cheapest) in `analysis.verdict`, the
terminal tables in `analysis.tables`.
"""

from ..measurements import evaluations_per_step as evaluations_per_step
from ..recording import environment_record as environment_record
from ..sweeps import (
    SolverSweep as SolverSweep,
    default_sweeps as default_sweeps,
    sweeps_for as sweeps_for,
    tolerance_pairs as tolerance_pairs,
)
from ._schedules import SCHEDULES as SCHEDULES, ScheduleReference as ScheduleReference
from ._study import (
    CSV_COLUMNS as CSV_COLUMNS,
    VERDICT_TARGETS as VERDICT_TARGETS,
    StudyConfig as StudyConfig,
    StudyResult as StudyResult,
    read_csv as read_csv,
    run_study as run_study,
    write_csv as write_csv,
    write_json as write_json,
    write_study as write_study,
)
