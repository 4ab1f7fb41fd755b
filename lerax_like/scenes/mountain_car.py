from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import FINITE, POSITIVE, POSITIVE_OR_INF, concrete
from .._types import Array, BoolScalar, Input, Key, Scalar, State
from ..env import AbstractEnv, EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics import MountainCarDynamics
from ..spaces import Box, Discrete
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv


class AbstractMountainCar(AbstractEnv):
    """What the discrete and continuous mountain cars share: road, start, projection, goal.

    The fields both declare with the same defaults are declared here, once; each concrete
    car adds its engine, its goal position and its episode limit.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    # Declared before the fields with defaults: an AbstractVar declares no field at run time,
    # but a type checker reads it as one without a default.
    goal_position: eqx.AbstractVar[Scalar]

    dynamics: MountainCarDynamics = eqx.field(default_factory=MountainCarDynamics)
    integrator: Integrator = eqx.field(default="semi_implicit_euler", converter=make_integrator)
    min_position: Scalar = eqx.field(default=-1.2, converter=FINITE)  # Gymnasium's units throughout
    max_position: Scalar = eqx.field(default=0.6, converter=FINITE)
    max_speed: Scalar = eqx.field(default=0.07, converter=POSITIVE_OR_INF)
    goal_velocity: Scalar = eqx.field(default=0.0, converter=FINITE)  # at least, at the goal
    dt: Scalar = eqx.field(default=1.0, converter=POSITIVE)

    @property
    def observation_space(self) -> Box:
        return Box(
            jnp.stack([self.min_position, -self.max_speed]), jnp.stack([self.max_position, self.max_speed])
        )

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        # The velocity's bounds coincide: it starts at rest, and is not drawn.
        return jnp.array([-0.6, 0.0], self.dt.dtype), jnp.array([-0.4, 0.0], self.dt.dtype)

    def project(self, y: State) -> State:
        # The speed limit, the ends of the road, and the left wall, which stops a car
        # that runs into it (Gymnasium's rules). Idempotent, so it can be applied both
        # after the velocity update and after the position update.
        position = jnp.clip(y[0], self.min_position, self.max_position)
        velocity = jnp.clip(y[1], -self.max_speed, self.max_speed)
        velocity = jnp.where((position == self.min_position) & (velocity < 0), 0.0, velocity)
        return jnp.stack([position, velocity])

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        position, velocity = state.y
        return (position >= self.goal_position) & (velocity >= self.goal_velocity)

    def __check_init__(self):
        low, high = concrete(self.min_position), concrete(self.max_position)
        if low is not None and high is not None and not np.all(low < high):
            raise ValueError(
                f"min_position must be < max_position (allowed range (-inf, max_position)), "
                f"got min_position={low}, max_position={high}"
            )


@register_scene
@final
class MountainCar(AbstractMountainCar):
    """Drive an underpowered car up a hill by rocking it (Gymnasium's MountainCar-v0).

    ## Description
    A car in a valley (`MountainCarDynamics`, Moore 1990), in units where the env step is
    the unit of time (`dt = 1`). With `solver="semi_implicit_euler"` (the default) a step
    is Gymnasium's: the velocity is updated and clipped to `max_speed`, the position is
    updated with the new velocity and clipped to the road, and a car that hits the left
    end (`min_position`) stops. With another solver, the same projection is applied after
    the step.

    ## Action Space
    `Discrete(3)`: accelerate left (`-force`), do nothing, accelerate right (`+force`).

    ## Observation Space
    `[position, velocity]`, within `[min_position, max_position] x [-max_speed, max_speed]`.

    ## Starting State
    Position uniform in `[-0.6, -0.4]`, velocity 0.

    ## Episode End
    Terminated when `position >= goal_position` and `velocity >= goal_velocity`, or when
    the integration fails (`info["solver_ok"]`). Truncated after `max_episode_steps`.

    ## Rewards
    -1 for every step.

    ## Arguments
    `dynamics` (a `MountainCarDynamics`) or `gravity` (0.0025) flat, `force` (0.001),
    `min_position` (-1.2), `max_position` (0.6), `max_speed` (0.07), `goal_position`
    (0.5), `goal_velocity` (0), `dt` (1), `integrator` or `solver` with
    `stepsize_controller`, `max_episode_steps` (200).
    """

    force: Scalar = eqx.field(default=0.001, converter=POSITIVE)
    goal_position: Scalar = eqx.field(default=0.5, converter=FINITE)
    max_episode_steps: int | None = episode_limit(200)

    @property
    def action_space(self) -> Discrete:
        return Discrete(3)

    def physical_input(self, action: Array) -> Input:
        return ((jnp.asarray(action).astype(self.force.dtype) - 1.0) * self.force)[None]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, action, next_state, key
        return -jnp.ones((), dtype=self.dt.dtype)

    @property
    def worst_reward(self) -> Scalar:
        return -jnp.ones((), dtype=self.dt.dtype)


@register_scene
@final
class MountainCarContinuous(AbstractMountainCar, AbstractUnitActionEnv):
    """Drive an underpowered car up a hill with a continuous throttle (MountainCarContinuous-v0).

    ## Description
    As `MountainCar`, with the engine's acceleration `power * action`, the action clipped
    to `[-1, 1]`.

    ## Action Space
    `Box(-1, 1, (1,))`: the throttle.

    ## Observation Space
    As `MountainCar`.

    ## Starting State
    As `MountainCar`.

    ## Episode End
    As `MountainCar`.

    ## Rewards
    `-0.1 * action**2` every step (on the action as given, before clipping, as Gymnasium
    does), plus 100 on the step that reaches the goal.

    ## Arguments
    `dynamics` (a `MountainCarDynamics`) or `gravity` (0.0025) flat, `power` (0.0015),
    `min_position` (-1.2), `max_position` (0.6), `max_speed` (0.07), `goal_position`
    (0.45), `goal_velocity` (0), `dt` (1), `integrator` or `solver` with
    `stepsize_controller`, `max_episode_steps` (999).
    """

    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "power"

    power: Scalar = eqx.field(default=0.0015, converter=POSITIVE)
    goal_position: Scalar = eqx.field(default=0.45, converter=FINITE)
    max_episode_steps: int | None = episode_limit(999)

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state
        goal = jnp.where(self.terminal(next_state, key=key), 100.0, 0.0).astype(self.dt.dtype)
        return goal - jnp.reshape(action, (1,))[0] ** 2 * 0.1

    @property
    def worst_reward(self) -> Scalar:
        # The throttle cost at the ends of the action space.
        return -0.1 * jnp.ones((), dtype=self.dt.dtype)
