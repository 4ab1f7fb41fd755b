from typing import ClassVar

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._checks import _concrete, as_parameter, check_finite, check_positive, check_positive_or_inf
from .._random import uniform
from .._types import Array, BoolScalar, Input, Key, Scalar, ScalarLike, State
from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, make_integrator
from ..physics import MountainCarDynamics
from ..spaces import Box, Discrete


SolverLike = "str | diffrax.AbstractSolver | Integrator"


def _check_road(min_position, max_position, goal_position) -> None:
    for name, value in [
        ("min_position", min_position), ("max_position", max_position), ("goal_position", goal_position),
    ]:
        check_finite(value, name)
    low, high = _concrete(min_position), _concrete(max_position)
    if low is not None and high is not None and not np.all(low < high):
        raise ValueError(
            f"min_position must be < max_position (allowed range (-inf, max_position)), "
            f"got min_position={low}, max_position={high}"
        )


def _road_parts(
    gravity, min_position, max_position, max_speed, goal_position, goal_velocity, dt, solver,
    stepsize_controller,
) -> tuple[MountainCarDynamics, Integrator, Scalar, Scalar, Scalar, Scalar, Scalar, Scalar]:
    """What both mountain cars build from their shared keywords, checked."""
    check_positive_or_inf(max_speed, "max_speed")
    check_finite(goal_velocity, "goal_velocity")
    check_positive(dt, "dt")
    _check_road(min_position, max_position, goal_position)
    return (
        MountainCarDynamics(gravity=gravity),
        make_integrator(solver, stepsize_controller),
        as_parameter(dt, "dt"),
        as_parameter(min_position, "min_position"),
        as_parameter(max_position, "max_position"),
        as_parameter(max_speed, "max_speed"),
        as_parameter(goal_position, "goal_position"),
        as_parameter(goal_velocity, "goal_velocity"),
    )


class AbstractMountainCar(AbstractEnv):
    """What the discrete and continuous mountain cars share: road, start, projection, goal."""

    dynamics: eqx.AbstractVar[MountainCarDynamics]
    min_position: eqx.AbstractVar[Scalar]
    max_position: eqx.AbstractVar[Scalar]
    max_speed: eqx.AbstractVar[Scalar]
    goal_position: eqx.AbstractVar[Scalar]
    goal_velocity: eqx.AbstractVar[Scalar]

    @property
    def observation_space(self) -> Box:
        return Box(
            jnp.stack([self.min_position, -self.max_speed]), jnp.stack([self.max_position, self.max_speed])
        )

    def initial(self, *, key: Key) -> EnvState:
        position = uniform(key, (), self.dt.dtype, -0.6, -0.4)
        y = jnp.stack([position, jnp.zeros_like(position)])
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def project(self, y: State) -> State:
        # The speed limit, the ends of the road, and the left wall, which stops a car
        # that runs into it (Gymnasium's rules). Idempotent, so it can be applied both
        # after the velocity update and after the position update.
        position = jnp.clip(y[0], self.min_position, self.max_position)
        velocity = jnp.clip(y[1], -self.max_speed, self.max_speed)
        velocity = jnp.where((position == self.min_position) & (velocity < 0), 0.0, velocity)
        return jnp.stack([position, velocity])

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        return state.y

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del key
        position, velocity = state.y
        return (position >= self.goal_position) & (velocity >= self.goal_velocity)


_COMMON_DOC = """
    ## Observation Space
    `[position, velocity]`, within `[min_position, max_position] x [-max_speed, max_speed]`.

    ## Starting State
    Position uniform in `[-0.6, -0.4]`, velocity 0.

    ## Episode End
    Terminated when `position >= goal_position` and `velocity >= goal_velocity`, or when
    the integration fails (`info["solver_ok"]`). Truncated after `max_episode_steps`.
"""


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

    ## Rewards
    -1 for every step.
    """ + _COMMON_DOC + """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    ## Arguments
    `gravity` (0.0025), `force` (0.001), `min_position` (-1.2), `max_position` (0.6),
    `max_speed` (0.07), `goal_position` (0.5), `goal_velocity` (0), `dt` (1), `solver`,
    `stepsize_controller`, `max_episode_steps` (200).
    """

    dynamics: MountainCarDynamics
    integrator: Integrator
    dt: Scalar
    force: Scalar
    min_position: Scalar
    max_position: Scalar
    max_speed: Scalar
    goal_position: Scalar
    goal_velocity: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        gravity: ScalarLike = 0.0025,
        force: ScalarLike = 0.001,
        min_position: ScalarLike = -1.2,
        max_position: ScalarLike = 0.6,
        max_speed: ScalarLike = 0.07,
        goal_position: ScalarLike = 0.5,
        goal_velocity: ScalarLike = 0.0,
        dt: ScalarLike = 1.0,
        solver: SolverLike = "semi_implicit_euler",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 200,
    ):
        check_positive(force, "force")
        (
            self.dynamics, self.integrator, self.dt, self.min_position, self.max_position,
            self.max_speed, self.goal_position, self.goal_velocity,
        ) = _road_parts(
            gravity, min_position, max_position, max_speed, goal_position, goal_velocity, dt,
            solver, stepsize_controller,
        )
        self.force = as_parameter(force, "force")
        self.max_episode_steps = max_episode_steps

    @property
    def action_space(self) -> Discrete:
        return Discrete(3)

    def physical_input(self, action: Array) -> Input:
        return ((jnp.asarray(action).astype(self.force.dtype) - 1.0) * self.force)[None]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, action, next_state, key
        return -jnp.ones((), dtype=self.dt.dtype)


class MountainCarContinuous(AbstractMountainCar):
    """Drive an underpowered car up a hill with a continuous throttle (MountainCarContinuous-v0).

    ## Description
    As `MountainCar`, with the engine's acceleration `power * action`, the action clipped
    to `[-1, 1]`.

    ## Action Space
    `Box(-1, 1, (1,))`: the throttle.

    ## Rewards
    `-0.1 * action**2` every step (on the action as given, before clipping, as Gymnasium
    does), plus 100 on the step that reaches the goal.
    """ + _COMMON_DOC + """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    ## Arguments
    `gravity` (0.0025), `power` (0.0015), `min_position` (-1.2), `max_position` (0.6),
    `max_speed` (0.07), `goal_position` (0.45), `goal_velocity` (0), `dt` (1), `solver`,
    `stepsize_controller`, `max_episode_steps` (999).
    """

    dynamics: MountainCarDynamics
    integrator: Integrator
    dt: Scalar
    power: Scalar
    min_position: Scalar
    max_position: Scalar
    max_speed: Scalar
    goal_position: Scalar
    goal_velocity: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        gravity: ScalarLike = 0.0025,
        power: ScalarLike = 0.0015,
        min_position: ScalarLike = -1.2,
        max_position: ScalarLike = 0.6,
        max_speed: ScalarLike = 0.07,
        goal_position: ScalarLike = 0.45,
        goal_velocity: ScalarLike = 0.0,
        dt: ScalarLike = 1.0,
        solver: SolverLike = "semi_implicit_euler",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 999,
    ):
        check_positive(power, "power")
        (
            self.dynamics, self.integrator, self.dt, self.min_position, self.max_position,
            self.max_speed, self.goal_position, self.goal_velocity,
        ) = _road_parts(
            gravity, min_position, max_position, max_speed, goal_position, goal_velocity, dt,
            solver, stepsize_controller,
        )
        self.power = as_parameter(power, "power")
        self.max_episode_steps = max_episode_steps

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (1,))

    def physical_input(self, action: Array) -> Input:
        return self.power * jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state
        goal = jnp.where(self.terminal(next_state, key=key), 100.0, 0.0).astype(self.dt.dtype)
        return goal - jnp.reshape(action, (1,))[0] ** 2 * 0.1
