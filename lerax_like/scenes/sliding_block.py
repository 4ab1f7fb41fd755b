from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import FINITE, NONNEGATIVE, POSITIVE
from .._types import Array, Scalar
from ..env import episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.friction import PlaneFriction
from ..physics.sliding_block import PlaneEnd, SlidingBlockDynamics
from ._registry import register_scene
from ._unit_action import AbstractReachEnv


@register_scene
@final
class SlidingBlock(AbstractReachEnv):
    """Push a block along an inclined plane with dry friction to a target position and hold it there.

    ## Description
    A block (`SlidingBlockDynamics`) on a plane inclined at `incline` (0: level), with
    Coulomb friction (`PlaneFriction`): it sticks until the load along the plane exceeds
    `static_friction * N` (`N = m g cos(incline)`), slides against `kinetic_friction * N`,
    and sticks again where its speed reaches zero if the load can be held. Each switch is
    an event located within the step (`lerax_like.stick_slip`), so a block at rest under
    a sub-threshold load stays exactly at rest, and gradients pass through the switches.

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range, scaled by `force_mag`: the force along the
    plane in newtons, positive up the slope.

    ## Observation Space
    The state `[s, v]`: position along the plane (m, positive up the slope) and its rate
    (m/s). Unbounded.

    ## Rewards
    `exp(-(s - target)**2) - action_cost * a**2` after the step, with `a` the clipped action:
    1 at the target, falling off with the distance.

    ## Starting State
    Position and speed uniform in `(-0.05, 0.05)`.

    ## Episode End
    Never terminated but by a failed step (`info["solver_ok"]`: more switches in a step than
    `max_events`, or an inconsistent slip); truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `SlidingBlockDynamics`) or its parameters flat: `mass`, `gravity`,
    `incline` (rad, in [0, pi/2)). The friction (`friction`, a one-tuple of `PlaneFriction`)
    or its parameters flat: `static_friction` (0.5) and `kinetic_friction` (0.3, at most the
    static one), `max_events` (switches per step). A wall across the plane (`contacts`, a
    one-tuple of `PlaneEnd`) or its parameters flat: `restitution` (none by default: no wall),
    `plane_end` (2 m), `min_rebound_speed`; it hits, rebounds and sticks where friction stops it. `force_mag` (10 N), `target` (1 m),
    `action_cost`, `dt` (0.05 s), `integrator` or `solver` (`"tsit5"` by default; `"rk4"`),
    `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False
    addons: ClassVar[tuple[type, ...]] = (PlaneFriction, PlaneEnd)
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "force_mag"

    dynamics: SlidingBlockDynamics = eqx.field(default_factory=SlidingBlockDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    friction: tuple = eqx.field(default_factory=lambda: (PlaneFriction(),))
    force_mag: Scalar = eqx.field(default=10.0, converter=POSITIVE)  # N
    target: Scalar = eqx.field(default=1.0, converter=FINITE)  # m along the plane
    action_cost: Scalar = eqx.field(default=1e-3, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.05, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(200)
    contacts: tuple = ()  # last, so that the fields given by position keep their places

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        return jnp.full(2, -0.05, self.dt.dtype), jnp.full(2, 0.05, self.dt.dtype)
