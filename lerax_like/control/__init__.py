"""Control and identification by gradients through the model: system identification by
multiple shooting (`fit_parameters`, and `fit_transitions` for one-step data), iLQR,
adaptive (refitting) MPC with the caller's costs, and in `lerax_like.control.learning`
policy learning (over a batch of envs that may each carry their own parameters: domain
randomisation, as in `notebooks/domain_randomisation.ipynb`) and open-loop trajectory
optimisation through the simulator."""

from .identification import (
    fit_parameters as fit_parameters,
    fit_transitions as fit_transitions,
    one_step_residuals as one_step_residuals,
    multiple_shooting_residuals as multiple_shooting_residuals,
)
from .ilqr import ilqr as ilqr
from .mpc import adaptive_mpc as adaptive_mpc, make_planner as make_planner
