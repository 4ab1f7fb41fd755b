"""Integrating a vector field over one env step with any diffrax solver.

One concept per module, as diffrax's `_solver/`: the solvers this package adds (`RK4`,
`SemiImplicitEuler`, `HermiteDenseOutput`), the `GuardedPIDController`, the root finders
of the implicit presets, `solver_facts` (order, stages, evaluations, error estimate: read
once, by every listing, study and count), the presets by name (`SOLVERS`), and the
`Integrator` that `make_integrator` builds from a preset name or a solver, refusing
pairings that would silently produce garbage, and how gradients pass through its solves
(the adjoint: `make_adjoint`, `with_adjoint`).
"""

from ._adjoint import (
    ADJOINTS as ADJOINTS,
    CHECKPOINTS as CHECKPOINTS,
    forward_mode_hint as forward_mode_hint,
    make_adjoint as make_adjoint,
    sized_to_the_work as sized_to_the_work,
    warn_if_silent as warn_if_silent,
    with_adjoint as with_adjoint,
)
from ._controller import GuardedPIDController as GuardedPIDController
from ._dense import HermiteDenseOutput as HermiteDenseOutput
from ._facts import SolverFacts as SolverFacts, has_error_estimate as has_error_estimate, solver_facts as solver_facts
from ._integrator import (
    EpisodeTime as EpisodeTime,
    Integrator as Integrator,
    make_integrator as make_integrator,
    tolerance_floors as tolerance_floors,
)
from ._presets import (
    SOLVERS as SOLVERS,
    SolverPreset as SolverPreset,
    SolverTable as SolverTable,
    describe_solver as describe_solver,
    register_solver as register_solver,
    solver_instance as solver_instance,
    unregister_solver as unregister_solver,
)
from ._rk4 import RK4 as RK4
from ._spec import solver_from_spec as solver_from_spec
from ._semi_implicit import ProjectedODETerm as ProjectedODETerm, SemiImplicitEuler as SemiImplicitEuler
