"""Control and identification by gradients through the model: system identification by
multiple shooting, gradient model-predictive control, adaptive (refitting) MPC."""

from .identification import (
    fit_parameters as fit_parameters,
    multiple_shooting_residuals as multiple_shooting_residuals,
)
from .ilqr import ilqr as ilqr
from .mpc import adaptive_mpc as adaptive_mpc
