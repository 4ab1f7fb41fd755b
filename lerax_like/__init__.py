"""Continuous-time control environments for JAX: physics as vector fields, any diffrax solver."""

from . import physics as physics, spaces as spaces
from .env import AbstractEnv as AbstractEnv, EnvState as EnvState, rollout as rollout
from .gradients import ADJOINTS as ADJOINTS, make_adjoint as make_adjoint, with_adjoint as with_adjoint
from .integrate import (
    Integrator as Integrator,
    RK4 as RK4,
    SOLVER_PRESETS as SOLVER_PRESETS,
    has_error_estimate as has_error_estimate,
    make_integrator as make_integrator,
)
from .physics import AbstractDynamics as AbstractDynamics, CartPoleDynamics as CartPoleDynamics
from .scenes import CartPole as CartPole, CartPoleContinuous as CartPoleContinuous
from .spaces import Box as Box, Discrete as Discrete

__version__ = "0.1.0"
