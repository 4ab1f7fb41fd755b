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
    SOLVERS as SOLVERS,
    SolverFacts as SolverFacts,
    SolverPreset as SolverPreset,
    describe_solver as describe_solver,
    has_error_estimate as has_error_estimate,
    make_integrator as make_integrator,
    register_solver as register_solver,
    solver_facts as solver_facts,
    solver_from_spec as solver_from_spec,
    unregister_solver as unregister_solver,
)
from .physics import (
    AbstractChainDynamics as AbstractChainDynamics,
    AbstractConservativeDynamics as AbstractConservativeDynamics,
    AbstractDynamics as AbstractDynamics,
    AbstractGeneralisedForce as AbstractGeneralisedForce,
    AcrobotDynamics as AcrobotDynamics,
    BallDynamics as BallDynamics,
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
    RimlessWheelDynamics as RimlessWheelDynamics,
    SlidingBlockDynamics as SlidingBlockDynamics,
    VanDerPolDynamics as VanDerPolDynamics,
    SimplestWalkerDynamics as SimplestWalkerDynamics,
    CompassGaitDynamics as CompassGaitDynamics,
)
from .scenes import (
    SCENES as SCENES,
    AbstractUnitActionEnv as AbstractUnitActionEnv,
    register_scene as register_scene,
    # Every scene of the package (`tests/test_public_surface.py` checks that none is missing).
    Acrobot as Acrobot,
    BouncingBall as BouncingBall,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
    DoubleCartPole as DoubleCartPole,
    MountainCar as MountainCar,
    MountainCarContinuous as MountainCarContinuous,
    NLinkPendulum as NLinkPendulum,
    Pendulum as Pendulum,
    PlanarQuadrotor as PlanarQuadrotor,
    RimlessWheel as RimlessWheel,
    SimplestWalker as SimplestWalker,
    SlidingBlock as SlidingBlock,
    VanDerPol as VanDerPol,
    CompassGait as CompassGait,
)
from .spaces import Box as Box, Discrete as Discrete

import importlib.metadata

try:  # pyproject.toml's version, through the installed package's metadata
    __version__ = importlib.metadata.version("lerax_like")
except importlib.metadata.PackageNotFoundError:  # a source tree on PYTHONPATH, not installed
    __version__ = "0+unknown"

# The Gymnasium ids (`gymnasium.make("lerax_like/CartPole-v1")`), registered on import.
from . import gym as gym

gym.register_envs()

# Stable-Baselines3 vector envs (`lerax_like.sb3.make_vec_env`); SB3 is imported on first use.
from . import sb3 as sb3

from ._module_attributes import deprecated_names as _deprecated_names

# Names that went (one name per concept), importable with a DeprecationWarning.
__getattr__ = _deprecated_names(
    __name__,
    {
        "SOLVER_PRESETS": ("lerax_like.SOLVERS.names", lambda: SOLVERS.names),
        # The Gymnasium layer's own names live in it, not beside the physics.
        "GymnasiumSpec": ("lerax_like.gym.GymnasiumSpec", lambda: gym.GymnasiumSpec),
    },
)

__all__ = [
    "AbstractChainDynamics",
    "AbstractConservativeDynamics",
    "AbstractDynamics",
    "AbstractEnv",
    "AbstractGeneralisedForce",
    "AbstractUnitActionEnv",
    "Acrobot",
    "AcrobotDynamics",
    "ADJOINTS",
    "BallDynamics",
    "BouncingBall",
    "Box",
    "CartChainDynamics",
    "CartPole",
    "CartPoleContinuous",
    "CartPoleDynamics",
    "CartFriction",
    "describe_solver",
    "Discrete",
    "DoubleCartPole",
    "EndStops",
    "EnvState",
    "FINITE",
    "ForcedDynamics",
    "gym",
    "has_error_estimate",
    "HermiteDenseOutput",
    "Integrator",
    "JointDamping",
    "make_adjoint",
    "make_integrator",
    "MountainCar",
    "MountainCarContinuous",
    "MountainCarDynamics",
    "NLinkPendulum",
    "NLinkPendulumDynamics",
    "NONNEGATIVE",
    "option",
    "parameter",
    "Pendulum",
    "PendulumDynamics",
    "PlaneFriction",
    "physics",
    "PlanarQuadrotor",
    "PlanarQuadrotorDynamics",
    "POSITIVE",
    "POSITIVE_OR_INF",
    "Range",
    "register_scene",
    "register_solver",
    "RimlessWheel",
    "SimplestWalker",
    "SlidingBlock",
    "SimplestWalkerDynamics",
    "SlidingBlockDynamics",
    "CompassGait",
    "CompassGaitDynamics",
    "RimlessWheelDynamics",
    "RK4",
    "rollout",
    "sb3",
    "SCENES",
    "SemiImplicitEuler",
    "solver_facts",
    "solver_from_spec",
    "SolverFacts",
    "SolverPreset",
    "SOLVERS",
    "spaces",
    "unregister_solver",
    "VanDerPol",
    "VanDerPolDynamics",
    "with_adjoint",
    "__version__",
]
