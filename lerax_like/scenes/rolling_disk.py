from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import FINITE, NONNEGATIVE, POSITIVE
from .._types import Array, Scalar
from ..env import episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.rolling_disk import DiskFloor, RollingDiskDynamics
from ._registry import register_scene
from ._unit_action import AbstractReachEnv


@register_scene
@final
class RollingDisk(AbstractReachEnv):
    """Roll a disk with a motor torque to a target position on a floor with friction, and hold it there.

    ## Description
    A disk in the vertical plane (`RollingDiskDynamics`) on a floor (`DiskFloor`) with
    Coulomb friction and Newton's restitution: launched sliding it skids and then rolls,
    thrown with backspin it comes back, dropped with speed it bounces with spin. A torque
    beyond what static friction can hold makes the wheel spin on the spot. Every impact and
    every stick/slip switch is an event located within the step (`lerax_like.floor_contact`),
    and gradients pass through them, event times included.

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range, scaled by `max_torque`: the motor's torque on
    the disk (N m, clockwise: positive drives it forward).

    ## Observation Space
    The state `[x, z, angle, x_dot, z_dot, angle_dot]` (m, rad clockwise, and their rates;
    `z` the centre's height, `radius` when touching the floor). Unbounded.

    ## Rewards
    `exp(-(x - target)**2) - action_cost * a**2` after the step, with `a` the clipped action:
    1 at the target, falling off with the distance.

    ## Starting State
    Resting on the floor (`z = radius`, `z_dot = 0`), `x`, `angle` and `x_dot` uniform in
    `(-0.05, 0.05)` and `angle_dot` in `(-0.5, 0.5)`: most starts slip, then roll.

    ## Episode End
    Never terminated but by a failed step (`info["solver_ok"]`: more located events in a step
    than `max_events`); truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `RollingDiskDynamics`; with `lerax_like.make`, its parameters flat:
    `radius`, `mass`, `inertia_factor` (I = inertia_factor * mass * radius**2), `gravity`).
    `floor` (a `DiskFloor`; flat: `static_friction`, `kinetic_friction`, `restitution`,
    `min_rebound_speed`, `max_events`). `max_torque` (1 N m), `target` (1 m),
    `action_cost`, `dt` (0.05 s), `integrator` or `solver` (`"tsit5"` by default),
    `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "max_torque"

    dynamics: RollingDiskDynamics = eqx.field(default_factory=RollingDiskDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    floor: DiskFloor = eqx.field(default_factory=DiskFloor)
    max_torque: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    target: Scalar = eqx.field(default=1.0, converter=FINITE)
    action_cost: Scalar = eqx.field(default=1e-3, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.05, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(200)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        dtype = self.dt.dtype
        radius = jnp.asarray(self.dynamics.radius, dtype)
        zero = jnp.zeros((), dtype)
        low = jnp.stack([zero - 0.05, radius, zero - 0.05, zero - 0.05, zero, zero - 0.5])
        high = jnp.stack([zero + 0.05, radius, zero + 0.05, zero + 0.05, zero, zero + 0.5])
        return low, high
