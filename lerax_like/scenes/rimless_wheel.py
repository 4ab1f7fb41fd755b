from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE
from .._types import Array, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.rimless_wheel import RimlessWheelDynamics, SpokeContact
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv


@register_scene
@final
class RimlessWheel(AbstractUnitActionEnv):
    """Roll a rimless wheel down a slope at a target speed with a bounded ankle torque.

    ## Description
    The passive walker of underactuated-robotics courses (`RimlessWheelDynamics`): a hub
    with spokes of length `leg_length`, `2 spoke_half_angle` apart, on a slope of
    `slope` radians. In stance it is an inverted pendulum about the stance foot; each
    heel strike (the next spoke landing) is located as an event within the step and
    followed by the impact map that conserves the angular momentum about the new foot
    (`SpokeContact`, `lerax_like.hybrid`), a rear strike likewise when the wheel rolls
    back. Passive (zero torque) and started fast enough to pass over the top, it settles
    onto its rolling limit cycle, whose post-impact speed is
    `dynamics.limit_cycle_speed` (1.0954628... rad/s with the defaults, Tedrake's and
    Drake's: 8 spokes, slope 0.08, l = 1, g = 9.81).

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range: the ankle torque `max_torque * a` (N m)
    at the stance foot, positive downhill.

    ## Observation Space
    `[theta, theta_dot]`: the stance spoke's angle from the vertical (rad, in
    `[slope - alpha, slope + alpha]`) and its rate (rad/s), positive downhill.

    ## Rewards
    `-min((theta_dot - target_speed)**2, max_cost) - action_cost * a**2` after the step:
    0 rolling at the target speed at no effort, never below `-max_cost - action_cost`.

    ## Starting State
    Just after a heel strike, `theta = slope - alpha`, with `theta_dot` uniform in
    `[1.1, 2.5]` times the speed that carries the hub over the top
    (`dynamics.speed_to_pass_the_top`).

    ## Episode End
    Never terminated, except when the integration fails (`info["solver_ok"]`, a step
    that would need more than `max_events` strikes). Truncated after
    `max_episode_steps` (400) steps.

    ## Arguments
    `dynamics` (a `RimlessWheelDynamics`) or its parameters flat: `leg_length` (1),
    `spoke_half_angle` (pi / 8), `slope` (0.08), `gravity` (9.81), `mass` (1). The
    contact (`contacts`, a `SpokeContact`) or its parameters flat:
    `min_rebound_speed` (1e-3 rad/s), `max_events` (32). `max_torque` (1), `target_speed`
    (1.5 rad/s), `max_cost`, `action_cost`, `dt` (0.05), `integrator` or `solver`
    (default `"tsit5"`) with `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # only the start is drawn at random
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "max_torque"
    addons: ClassVar[tuple[type, ...]] = (SpokeContact,)

    dynamics: RimlessWheelDynamics = eqx.field(default_factory=RimlessWheelDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    contacts: tuple = eqx.field(default_factory=lambda: (SpokeContact(),))  # the spokes' heel strikes
    max_torque: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # N m
    target_speed: Scalar = eqx.field(default=1.5, converter=POSITIVE)  # rad/s
    max_cost: Scalar = eqx.field(default=25.0, converter=POSITIVE)
    action_cost: Scalar = eqx.field(default=0.01, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.05, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(400)  # 20 s at dt = 0.05 s

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        dtype = self.dt.dtype
        wheel = self.dynamics
        theta = (wheel.slope - wheel.spoke_half_angle).astype(dtype)
        over = wheel.speed_to_pass_the_top.astype(dtype)
        return jnp.stack([theta, 1.1 * over]), jnp.stack([theta, 2.5 * over])

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        error = (next_state.y[1] - self.target_speed) ** 2
        return -jnp.minimum(error, self.max_cost) - self.action_cost * self.effort(action)

    @property
    def worst_reward(self) -> Scalar:
        return -self.max_cost - self.action_cost
