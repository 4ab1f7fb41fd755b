"""The keywords that constructors share, declared once for a static type checker (PEP 692).

Written by `python -m lerax_like._constructor_source --write` from the signatures read off
the fields (`lerax_like._signatures`); a dynamics takes its own as `**keywords`, and a scene
those of its abstract bases' fields, its dynamics, the integrator and its add-ons, composed.
`<Class>Keywords` are the keywords of that dynamics, or of that add-on as a scene takes them
flat (None: absent, unless given). A TypedDict holds no defaults: `inspect.signature` shows them.
"""

from collections.abc import Sequence
from typing import Literal, TypedDict

import diffrax

from lerax_like._types import ArrayLike, ScalarLike
from lerax_like.integrate import Integrator
from lerax_like.physics.cartpole import CartPoleDynamics
from lerax_like.physics.mountain_car import MountainCarDynamics


class IntegratorKeywords(TypedDict, total=False):
    """A scene's `integrator`, or the settings that build one with `make_integrator`."""

    integrator: Integrator
    solver: str | diffrax.AbstractSolver | Integrator
    stepsize_controller: diffrax.AbstractStepSizeController | None
    max_steps: int | None
    adjoint: diffrax.AbstractAdjoint | None
    substeps: int


class AbstractCartPoleKeywords(TypedDict, total=False):
    """The fields `AbstractCartPole` declares, once, for the final scenes built on it."""

    dynamics: CartPoleDynamics
    forces: tuple
    contacts: tuple
    friction: tuple
    force_mag: ScalarLike
    theta_threshold_radians: ScalarLike
    x_threshold: ScalarLike
    dt: ScalarLike
    max_episode_steps: int | None


class AbstractMountainCarKeywords(TypedDict, total=False):
    """The fields `AbstractMountainCar` declares, once, for the final scenes built on it."""

    dynamics: MountainCarDynamics
    min_position: ScalarLike
    max_position: ScalarLike
    max_speed: ScalarLike
    goal_velocity: ScalarLike
    dt: ScalarLike


class EventBudgetKeywords(TypedDict, total=False):
    """The located events (impacts, stick-slip switches) allowed per env step."""

    max_events: int | None


class CartFrictionKeywords(EventBudgetKeywords, total=False):
    cart_static_friction: ScalarLike | None
    cart_kinetic_friction: ScalarLike | None


class EndStopsKeywords(TypedDict, total=False):
    end_stop_stiffness: ScalarLike | None
    end_stop_damping: ScalarLike | None
    track_limit: ScalarLike | None


class FloorAndWallKeywords(EventBudgetKeywords, total=False):
    restitution: ScalarLike | None
    wall_position: ScalarLike | None
    min_rebound_speed: ScalarLike | None


class HeelStrikeKeywords(EventBudgetKeywords, total=False): ...


class JointDampingKeywords(TypedDict, total=False):
    joint_damping: ScalarLike | None


class PlaneFrictionKeywords(EventBudgetKeywords, total=False):
    static_friction: ScalarLike | None
    kinetic_friction: ScalarLike | None


class SpokeContactKeywords(EventBudgetKeywords, total=False):
    min_rebound_speed: ScalarLike | None


class WallsKeywords(EventBudgetKeywords, total=False):
    restitution: ScalarLike | None
    track_limit: ScalarLike | None
    min_rebound_speed: ScalarLike | None


class AcrobotDynamicsKeywords(TypedDict, total=False):
    gravity: ScalarLike
    link_length_1: ScalarLike
    link_mass_1: ScalarLike
    link_mass_2: ScalarLike
    link_com_position_1: ScalarLike
    link_com_position_2: ScalarLike
    link_moment_of_inertia_1: ScalarLike
    link_moment_of_inertia_2: ScalarLike
    equations: Literal['book', 'nips']


class BallDynamicsKeywords(TypedDict, total=False):
    mass: ScalarLike
    gravity: ScalarLike


class CartChainDynamicsKeywords(TypedDict, total=False):
    cart_mass: ScalarLike
    pole_masses: ArrayLike | Sequence[float]
    pole_lengths: ArrayLike | Sequence[float]
    gravity: ScalarLike


class CartPoleDynamicsKeywords(TypedDict, total=False):
    gravity: ScalarLike
    cart_mass: ScalarLike
    pole_mass: ScalarLike
    half_length: ScalarLike


class CompassGaitDynamicsKeywords(TypedDict, total=False):
    lower_length: ScalarLike
    upper_length: ScalarLike
    leg_mass: ScalarLike
    hip_mass: ScalarLike
    slope: ScalarLike
    gravity: ScalarLike


class MountainCarDynamicsKeywords(TypedDict, total=False):
    gravity: ScalarLike


class NLinkPendulumDynamicsKeywords(TypedDict, total=False):
    masses: ArrayLike | Sequence[float]
    lengths: ArrayLike | Sequence[float]
    gravity: ScalarLike


class PendulumDynamicsKeywords(TypedDict, total=False):
    gravity: ScalarLike
    mass: ScalarLike
    length: ScalarLike


class PlanarQuadrotorDynamicsKeywords(TypedDict, total=False):
    mass: ScalarLike
    arm_length: ScalarLike
    moment_of_inertia: ScalarLike
    gravity: ScalarLike


class RimlessWheelDynamicsKeywords(TypedDict, total=False):
    leg_length: ScalarLike
    spoke_half_angle: ScalarLike
    slope: ScalarLike
    gravity: ScalarLike
    mass: ScalarLike


class SimplestWalkerDynamicsKeywords(TypedDict, total=False):
    slope: ScalarLike


class SlidingBlockDynamicsKeywords(TypedDict, total=False):
    mass: ScalarLike
    gravity: ScalarLike
    incline: ScalarLike


class VanDerPolDynamicsKeywords(TypedDict, total=False):
    mu: ScalarLike


__all__ = [
    "IntegratorKeywords", "AbstractCartPoleKeywords", "AbstractMountainCarKeywords",
    "EventBudgetKeywords", "CartFrictionKeywords", "EndStopsKeywords", "FloorAndWallKeywords",
    "HeelStrikeKeywords", "JointDampingKeywords", "PlaneFrictionKeywords", "SpokeContactKeywords",
    "WallsKeywords", "AcrobotDynamicsKeywords", "BallDynamicsKeywords", "CartChainDynamicsKeywords",
    "CartPoleDynamicsKeywords", "CompassGaitDynamicsKeywords", "MountainCarDynamicsKeywords",
    "NLinkPendulumDynamicsKeywords", "PendulumDynamicsKeywords", "PlanarQuadrotorDynamicsKeywords",
    "RimlessWheelDynamicsKeywords", "SimplestWalkerDynamicsKeywords", "SlidingBlockDynamicsKeywords",
    "VanDerPolDynamicsKeywords"
]
