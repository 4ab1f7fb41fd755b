"""Continuous-time control environments for JAX: physics as vector fields, any diffrax solver."""

from . import physics as physics, spaces as spaces
# How dynamics and scenes declare their fields, checked by name at construction.
from ._fields import (
    FINITE as FINITE,
    NONNEGATIVE as NONNEGATIVE,
    POSITIVE as POSITIVE,
    POSITIVE_OR_INF as POSITIVE_OR_INF,
    Range as Range,
    option as option,
    parameter as parameter,
)
from .env import (
    AbstractEnv as AbstractEnv,
    EnvState as EnvState,
    rollout as rollout,
)
from .gradients import ADJOINTS as ADJOINTS, make_adjoint as make_adjoint, with_adjoint as with_adjoint
from .integrate import (
    HermiteDenseOutput as HermiteDenseOutput,
    Integrator as Integrator,
    RK4 as RK4,
    SemiImplicitEuler as SemiImplicitEuler,
    SOLVER_PRESETS as SOLVER_PRESETS,
    SOLVERS as SOLVERS,
    SolverFacts as SolverFacts,
    SolverPreset as SolverPreset,
    describe_solver as describe_solver,
    has_error_estimate as has_error_estimate,
    make_integrator as make_integrator,
    register_solver as register_solver,
    solver_facts as solver_facts,
    unregister_solver as unregister_solver,
)
from .cli import solver_from_spec as solver_from_spec
from .physics import (
    AbstractChainDynamics as AbstractChainDynamics,
    AbstractConservativeDynamics as AbstractConservativeDynamics,
    AbstractDynamics as AbstractDynamics,
    AbstractGeneralisedForce as AbstractGeneralisedForce,
    AcrobotDynamics as AcrobotDynamics,
    CartChainDynamics as CartChainDynamics,
    CartFriction as CartFriction,
    CartPoleDynamics as CartPoleDynamics,
    EndStops as EndStops,
    ForcedDynamics as ForcedDynamics,
    JointDamping as JointDamping,
    MountainCarDynamics as MountainCarDynamics,
    NLinkPendulumDynamics as NLinkPendulumDynamics,
    PendulumDynamics as PendulumDynamics,
    PlaneFriction as PlaneFriction,
    PlanarQuadrotorDynamics as PlanarQuadrotorDynamics,
    SlidingBlockDynamics as SlidingBlockDynamics,
    VanDerPolDynamics as VanDerPolDynamics,
)
from .scenes import SCENES as SCENES, AbstractUnitActionEnv as AbstractUnitActionEnv, register_scene as register_scene

# Every registered scene at the top level (`lerax_like.CartPole`), from the one registry.
globals().update(SCENES)
from .spaces import Box as Box, Discrete as Discrete

__version__ = "0.1.0"

# The Gymnasium ids (`gymnasium.make("lerax_like/CartPole-v1")`), registered on import.
from . import gym as gym
from .gym import GymnasiumSpec as GymnasiumSpec

gym.register_envs()

# Stable-Baselines3 vector envs (`lerax_like.sb3.make_vec_env`); SB3 is imported on first use.
from . import sb3 as sb3
