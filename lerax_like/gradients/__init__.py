"""Gradients through the envs: the adjoint, checks against finite differences, estimators,
sensitivities and Lyapunov exponents.

One concept per private module, the public names re-exported here:

- how gradients pass through an env's solves (`ADJOINTS`, `make_adjoint`, `with_adjoint`,
  `CHECKPOINTS`) is the integrator's configuration: `lerax_like.integrate`, re-exported here;
- `_gradcheck`: autodiff against central finite differences, leaf by leaf (`gradcheck`);
- `_estimators`: the first-order, zeroth-order and interpolated estimators of the gradient
  of a Gaussian-smoothed objective, and their unbiased reference (`estimate_gradients`);
- `_sensitivity`: `d y(t_k) / d p` along a rollout and where the solver gets its sign wrong
  against Dopri8 at tight tolerances (`trajectory_sensitivity`, `sensitivity_signs`);
- `_lyapunov`: finite-time Lyapunov exponents of a step map (`finite_time_lyapunov`).

The tools take values (a function, a tree, a state, arrays), not a study's configuration;
the studies that use them are in `lerax_like.analysis`. They sit above the env and the
integrator, which they use; nothing here imports SciPy at module level.
"""

from ..integrate import (
    ADJOINTS as ADJOINTS,
    CHECKPOINTS as CHECKPOINTS,
    make_adjoint as make_adjoint,
    with_adjoint as with_adjoint,
)
from ._estimators import (
    ESTIMATORS as ESTIMATORS,
    Evaluators as Evaluators,
    alpha_weight as alpha_weight,
    estimate_gradients as estimate_gradients,
    per_sample_statistics as per_sample_statistics,
)
from ._gradcheck import (
    GradCheckReport as GradCheckReport,
    LeafCheck as LeafCheck,
    gradcheck as gradcheck,
    selection_spec as selection_spec,
)
from ._lyapunov import finite_time_lyapunov as finite_time_lyapunov
from ._sensitivity import (
    reference_integrator as reference_integrator,
    sensitivity_signs as sensitivity_signs,
    trajectory_sensitivity as trajectory_sensitivity,
    with_integrator as with_integrator,
)

__all__ = [
    "ADJOINTS",
    "CHECKPOINTS",
    "ESTIMATORS",
    "Evaluators",
    "GradCheckReport",
    "LeafCheck",
    "alpha_weight",
    "estimate_gradients",
    "finite_time_lyapunov",
    "gradcheck",
    "make_adjoint",
    "per_sample_statistics",
    "reference_integrator",
    "selection_spec",
    "sensitivity_signs",
    "trajectory_sensitivity",
    "with_adjoint",
    "with_integrator",
]
