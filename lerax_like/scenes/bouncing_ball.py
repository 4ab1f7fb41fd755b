from typing import TYPE_CHECKING, ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import FINITE, NONNEGATIVE, POSITIVE, parameter
from .._types import Array, BoolScalar, Key, Scalar
from ..env import EnvState, dynamics, episode_limit, integrator, time_step
from ..integrate import Integrator
from ..physics.ball import BallDynamics, FloorAndWall
from ._unit_action import AbstractUnitActionEnv


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

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import BallDynamicsKeywords, FloorAndWallKeywords, IntegratorKeywords
        from lerax_like._types import ScalarLike

        class _Keywords(BallDynamicsKeywords, IntegratorKeywords, FloorAndWallKeywords, total=False): ...

        def __init__(
            self,
            *,
            dynamics: BallDynamics = ...,
            contacts: tuple = ...,
            max_thrust: ScalarLike = 20.0,
            target_x: ScalarLike = 0.5,
            target_z: ScalarLike = 1.0,
            left_limit: ScalarLike = 2.0,
            ceiling: ScalarLike = 4.0,
            max_distance: ScalarLike = 5.0,
            action_cost: ScalarLike = 0.01,
            dt: ScalarLike = 0.02,
            max_episode_steps: int | None = 200,
            **keywords: Unpack[_Keywords],
        ) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 2
    action_scale: ClassVar[str] = "max_thrust"
    addons: ClassVar[tuple[type, ...]] = (FloorAndWall,)

    dynamics: BallDynamics = dynamics(BallDynamics)
    integrator: Integrator = integrator("tsit5")
    contacts: tuple = eqx.field(default_factory=lambda: (FloorAndWall(),))
    max_thrust: Scalar = parameter(20.0, POSITIVE)
    target_x: Scalar = parameter(0.5, FINITE)
    target_z: Scalar = parameter(1.0, FINITE)
    left_limit: Scalar = parameter(2.0, POSITIVE)
    ceiling: Scalar = parameter(4.0, POSITIVE)
    max_distance: Scalar = parameter(5.0, POSITIVE)
    action_cost: Scalar = parameter(0.01, NONNEGATIVE)
    dt: Scalar = time_step(0.02)
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
