from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import FINITE, NONNEGATIVE, POSITIVE
from .._types import Array, BoolScalar, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.ball import BallDynamics, FloorAndWall
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv


@register_scene
@final
class BouncingBall(AbstractUnitActionEnv):
    """Steer a bouncing ball with a bounded thrust to a target point and hold it there.

    ## Description
    A point mass in the vertical plane (`BallDynamics`) under gravity, with a floor at
    `z = 0` and a wall at `x = wall_position` (`FloorAndWall`, restitution `e`). Every
    impact is located as an event within the step and followed by the impulse map
    (`lerax_like.hybrid`); a rebound slower than `min_rebound_speed` leaves the ball
    resting on the surface until the surface would have to pull. The smallest contact
    case, and the one the gradient studies use: gradients pass through the impacts, event
    times included (they grow like one over the normal speed near a grazing contact).

    ## Action Space
    `Box(-1, 1, (2,))`, clipped to that range: the thrust `max_thrust * a` (N) on the
    ball, horizontal and vertical.

    ## Observation Space
    The state `[x, z, x_dot, z_dot]` (m, m/s), unbounded.

    ## Rewards
    `-min(d, max_distance) - action_cost * |a|^2` after the step, `d` the distance from
    the ball to `(target_x, target_z)` and `a` the clipped action: 0 at the target at no
    effort, never below `-max_distance - 2 action_cost`.

    ## Starting State
    At rest, `x` uniform in `(-0.5, 0.5)` m and `z` in `(0.5, 1.5)` m.

    ## Episode End
    Terminated when `x < -left_limit` or `z > ceiling` (the ball left the arena), or
    when the integration fails (`info["solver_ok"]`: a step that would need more than
    `max_events` impacts among them). Truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `BallDynamics`) or its parameters flat: `mass`, `gravity`. The contact
    (`contacts`, a `FloorAndWall`) or its parameters flat: `restitution` (in [0, 1]),
    `wall_position`, `min_rebound_speed`, `max_events`. `max_thrust`, `target_x`,
    `target_z`, `left_limit`, `ceiling`, `max_distance`, `action_cost`, `dt`, `integrator`
    or `solver` (default `"tsit5"`) with `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 2
    action_scale: ClassVar[str] = "max_thrust"
    addons: ClassVar[tuple[type, ...]] = (FloorAndWall,)

    dynamics: BallDynamics = eqx.field(default_factory=BallDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    contacts: tuple = eqx.field(default_factory=lambda: (FloorAndWall(),))
    max_thrust: Scalar = eqx.field(default=20.0, converter=POSITIVE)  # N, each jet
    target_x: Scalar = eqx.field(default=0.5, converter=FINITE)  # m
    target_z: Scalar = eqx.field(default=1.0, converter=FINITE)  # m
    left_limit: Scalar = eqx.field(default=2.0, converter=POSITIVE)  # m
    ceiling: Scalar = eqx.field(default=4.0, converter=POSITIVE)  # m
    max_distance: Scalar = eqx.field(default=5.0, converter=POSITIVE)  # m
    action_cost: Scalar = eqx.field(default=0.01, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(200)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        dtype = self.dt.dtype
        return jnp.array([-0.5, 0.5, 0.0, 0.0], dtype), jnp.array([0.5, 1.5, 0.0, 0.0], dtype)

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        offset = next_state.y[:2] - jnp.stack([self.target_x, self.target_z])
        # The distance's gradient is undefined at the target itself; its square is not.
        distance = jnp.sqrt(jnp.sum(offset**2) + jnp.finfo(offset.dtype).tiny)
        return -jnp.minimum(distance, self.max_distance) - self.action_cost * self.effort(action)

    @property
    def worst_reward(self) -> Scalar:
        return -self.max_distance - 2 * self.action_cost

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        x, z = state.y[:2]
        return (x < -self.left_limit) | (z > self.ceiling)
