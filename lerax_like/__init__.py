"""Continuous-time control environments for JAX: physics as vector fields, any diffrax solver."""

from . import physics as physics, spaces as spaces
from .env import AbstractEnv as AbstractEnv, EnvState as EnvState, rollout as rollout
from .gradients import ADJOINTS as ADJOINTS, make_adjoint as make_adjoint, with_adjoint as with_adjoint
from .integrate import (
    Integrator as Integrator,
    RK4 as RK4,
    SemiImplicitEuler as SemiImplicitEuler,
    SOLVER_PRESETS as SOLVER_PRESETS,
    has_error_estimate as has_error_estimate,
    make_integrator as make_integrator,
)
from .physics import AbstractDynamics as AbstractDynamics, CartPoleDynamics as CartPoleDynamics
from .physics import (
    AcrobotDynamics as AcrobotDynamics,
    MountainCarDynamics as MountainCarDynamics,
    PendulumDynamics as PendulumDynamics,
)
from .scenes import CartPole as CartPole, CartPoleContinuous as CartPoleContinuous
from .scenes import (
    Acrobot as Acrobot,
    MountainCar as MountainCar,
    MountainCarContinuous as MountainCarContinuous,
    Pendulum as Pendulum,
)
from .physics import VanDerPolDynamics as VanDerPolDynamics
from .scenes import VanDerPol as VanDerPol
from .spaces import Box as Box, Discrete as Discrete
from .physics import CartChainDynamics as CartChainDynamics, NLinkPendulumDynamics as NLinkPendulumDynamics
from .scenes import DoubleCartPole as DoubleCartPole, NLinkPendulum as NLinkPendulum

__version__ = "0.1.0"

# The Gymnasium ids (`gymnasium.make("lerax_like/CartPole-v1")`), registered on import.
from . import gym as gym

gym.register_envs()
