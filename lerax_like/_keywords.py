"""The keywords that constructors share, declared once for a static type checker (PEP 692).

Written by `python -m lerax_like._constructor_source --write` from the signatures read off
the fields (`lerax_like._signatures`); a dynamics takes its own as `**keywords`, and a scene
those of its abstract bases' fields, its dynamics, the integrator and its add-ons, composed.
A TypedDict holds no defaults: `inspect.signature` shows them."""

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


class CartFrictionKeywords(TypedDict, total=False):
    """The keywords of `CartFriction` as a scene takes them flat (absent unless given)."""

    max_events: int | None
    cart_static_friction: ScalarLike | None
    cart_kinetic_friction: ScalarLike | None


class EndStopsKeywords(TypedDict, total=False):
    """The keywords of `EndStops` as a scene takes them flat (absent unless given)."""

    end_stop_stiffness: ScalarLike | None
    end_stop_damping: ScalarLike | None
    track_limit: ScalarLike | None


class FloorAndWallKeywords(TypedDict, total=False):
    """The keywords of `FloorAndWall` as a scene takes them flat (absent unless given)."""

    max_events: int | None
    restitution: ScalarLike | None
    wall_position: ScalarLike | None
    min_rebound_speed: ScalarLike | None


class HeelStrikeKeywords(TypedDict, total=False):
    """The keywords of `HeelStrike` as a scene takes them flat (absent unless given)."""

    max_events: int | None


class JointDampingKeywords(TypedDict, total=False):
    """The keywords of `JointDamping` as a scene takes them flat (absent unless given)."""

    joint_damping: ScalarLike | None


class PlaneFrictionKeywords(TypedDict, total=False):
    """The keywords of `PlaneFriction` as a scene takes them flat (absent unless given)."""

    max_events: int | None
    static_friction: ScalarLike | None
    kinetic_friction: ScalarLike | None


class SpokeContactKeywords(TypedDict, total=False):
    """The keywords of `SpokeContact` as a scene takes them flat (absent unless given)."""

    max_events: int | None
    min_rebound_speed: ScalarLike | None


class WallsKeywords(TypedDict, total=False):
    """The keywords of `Walls` as a scene takes them flat (absent unless given)."""

    max_events: int | None
    restitution: ScalarLike | None
    track_limit: ScalarLike | None
    min_rebound_speed: ScalarLike | None


class AcrobotDynamicsKeywords(TypedDict, total=False):
    """The keywords of `AcrobotDynamics`, which a scene built on it takes flat too."""

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
    """The keywords of `BallDynamics`, which a scene built on it takes flat too."""

    mass: ScalarLike
    gravity: ScalarLike


class CartChainDynamicsKeywords(TypedDict, total=False):
    """The keywords of `CartChainDynamics`, which a scene built on it takes flat too."""

    cart_mass: ScalarLike
    pole_masses: ArrayLike | Sequence[float]
    pole_lengths: ArrayLike | Sequence[float]
    gravity: ScalarLike


class CartPoleDynamicsKeywords(TypedDict, total=False):
    """The keywords of `CartPoleDynamics`, which a scene built on it takes flat too."""

    gravity: ScalarLike
    cart_mass: ScalarLike
    pole_mass: ScalarLike
    half_length: ScalarLike


class CompassGaitDynamicsKeywords(TypedDict, total=False):
    """The keywords of `CompassGaitDynamics`, which a scene built on it takes flat too."""

    lower_length: ScalarLike
    upper_length: ScalarLike
    leg_mass: ScalarLike
    hip_mass: ScalarLike
    slope: ScalarLike
    gravity: ScalarLike


class MountainCarDynamicsKeywords(TypedDict, total=False):
    """The keywords of `MountainCarDynamics`, which a scene built on it takes flat too."""

    gravity: ScalarLike


class NLinkPendulumDynamicsKeywords(TypedDict, total=False):
    """The keywords of `NLinkPendulumDynamics`, which a scene built on it takes flat too."""

    masses: ArrayLike | Sequence[float]
    lengths: ArrayLike | Sequence[float]
    gravity: ScalarLike


class PendulumDynamicsKeywords(TypedDict, total=False):
    """The keywords of `PendulumDynamics`, which a scene built on it takes flat too."""

    gravity: ScalarLike
    mass: ScalarLike
    length: ScalarLike


class PlanarQuadrotorDynamicsKeywords(TypedDict, total=False):
    """The keywords of `PlanarQuadrotorDynamics`, which a scene built on it takes flat too."""

    mass: ScalarLike
    arm_length: ScalarLike
    moment_of_inertia: ScalarLike
    gravity: ScalarLike


class RimlessWheelDynamicsKeywords(TypedDict, total=False):
    """The keywords of `RimlessWheelDynamics`, which a scene built on it takes flat too."""

    leg_length: ScalarLike
    spoke_half_angle: ScalarLike
    slope: ScalarLike
    gravity: ScalarLike
    mass: ScalarLike


class SimplestWalkerDynamicsKeywords(TypedDict, total=False):
    """The keywords of `SimplestWalkerDynamics`, which a scene built on it takes flat too."""

    slope: ScalarLike


class SlidingBlockDynamicsKeywords(TypedDict, total=False):
    """The keywords of `SlidingBlockDynamics`, which a scene built on it takes flat too."""

    mass: ScalarLike
    gravity: ScalarLike
    incline: ScalarLike


class VanDerPolDynamicsKeywords(TypedDict, total=False):
    """The keywords of `VanDerPolDynamics`, which a scene built on it takes flat too."""

    mu: ScalarLike


__all__ = [
    "IntegratorKeywords", "AbstractCartPoleKeywords", "AbstractMountainCarKeywords",
    "CartFrictionKeywords", "EndStopsKeywords", "FloorAndWallKeywords", "HeelStrikeKeywords",
    "JointDampingKeywords", "PlaneFrictionKeywords", "SpokeContactKeywords", "WallsKeywords",
    "AcrobotDynamicsKeywords", "BallDynamicsKeywords", "CartChainDynamicsKeywords",
    "CartPoleDynamicsKeywords", "CompassGaitDynamicsKeywords", "MountainCarDynamicsKeywords",
    "NLinkPendulumDynamicsKeywords", "PendulumDynamicsKeywords", "PlanarQuadrotorDynamicsKeywords",
    "RimlessWheelDynamicsKeywords", "SimplestWalkerDynamicsKeywords", "SlidingBlockDynamicsKeywords",
    "VanDerPolDynamicsKeywords"
]
