"""What the Gymnasium layer knows of each registered id, in one table.

Everything id-specific lives here: which scene to build, Gymnasium's time limit and
reward threshold, how Gymnasium's env draws its initial state from `np_random`, and
how to hand a state to Gymnasium's renderer. The env wrappers are generic.
"""

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from gymnasium.envs.classic_control import utils as classic_utils


InitialState = Callable[[np.random.Generator, dict[str, Any] | None, int], np.ndarray]
"""`(np_random, reset options, num_envs) -> states`, float64 of shape `(n, num_envs)`."""

RenderSync = Callable[[Any, Any, np.ndarray, np.ndarray | None], None]
"""`(gymnasium env, scene, state, last action or None)`: prepare Gymnasium's renderer."""


@dataclasses.dataclass(frozen=True)
class GymSpec:
    """One registered id: `lerax_like/<name>` stands in for Gymnasium's `<name>`.

    - `name`: Gymnasium's id, e.g. `"CartPole-v1"`.
    - `scene`: the name of the scene class in `lerax_like.scenes`.
    - `max_episode_steps`, `reward_threshold`: Gymnasium's, for the registry.
    - `initial_state`: draws initial states exactly as Gymnasium's env does with the same
      generator (same calls, same order), for `num_envs` envs at once: one column each.
    - `renderer`: the Gymnasium class whose `render` draws the scene, and `render_sync`,
      which copies our state and drawing parameters into an instance of it.
    """

    name: str
    scene: str
    max_episode_steps: int
    reward_threshold: float | None
    initial_state: InitialState
    renderer: str
    render_sync: RenderSync

    @property
    def id(self) -> str:
        return f"lerax_like/{self.name}"


def _uniform(default_low: float, default_high: float, n: int, *, round_to_float32: bool = False) -> InitialState:
    """`n` coordinates uniform in `[low, high)`, bounds from the `low`/`high` reset options.

    Gymnasium draws `uniform(size=(n,))` for one env and `uniform(size=(n, num_envs))` for
    its vector CartPole; both consume the generator in the same order.
    """

    def initial_state(np_random, options, num_envs):
        low, high = classic_utils.maybe_parse_reset_bounds(options, default_low, default_high)
        state = np_random.uniform(low=low, high=high, size=(n, num_envs))
        if round_to_float32:
            # Acrobot stores its initial state in float32.
            state = state.astype(np.float32)
        return state.astype(np.float64)

    return initial_state


def _pendulum_initial_state(np_random, options, num_envs):
    # Pendulum: angle uniform in [-x_init, x_init), velocity in [-y_init, y_init).
    if options is None:
        x, y = math.pi, 1.0
    else:
        x = classic_utils.verify_number_and_cast(options.get("x_init", math.pi))
        y = classic_utils.verify_number_and_cast(options.get("y_init", 1.0))
    high = np.array([[x], [y]])
    return np_random.uniform(low=-high, high=high, size=(2, num_envs))


def _mountain_car_initial_state(np_random, options, num_envs):
    # Both mountain cars: one uniform position in [-0.6, -0.4), at rest.
    low, high = classic_utils.maybe_parse_reset_bounds(options, -0.6, -0.4)
    position = np_random.uniform(low=low, high=high, size=(num_envs,))
    return np.stack([position, np.zeros(num_envs)])


def _float(x) -> float:
    return float(np.asarray(x))


def _sync_cartpole(gym_env, scene, state, action):
    gym_env.state = state
    gym_env.x_threshold = _float(scene.x_threshold)
    gym_env.length = _float(scene.dynamics.half_length)


def _sync_state(gym_env, scene, state, action):
    gym_env.state = state


def _sync_pendulum(gym_env, scene, state, action):
    gym_env.state = state
    # Gymnasium draws the clipped torque of the last step as an arrow (none after reset).
    if action is None:
        gym_env.last_u = None
    else:
        low, high = scene.action_space.low, scene.action_space.high
        gym_env.last_u = _float(np.clip(np.asarray(action).reshape(-1)[0], np.asarray(low)[0], np.asarray(high)[0]))


def _sync_acrobot(gym_env, scene, state, action):
    gym_env.state = state
    for attribute, name in (("LINK_LENGTH_1", "link_length_1"), ("LINK_LENGTH_2", "link_length_2")):
        value = getattr(scene.dynamics, name, None)
        if value is not None:
            setattr(gym_env, attribute, _float(value))


def _sync_mountain_car(gym_env, scene, state, action):
    gym_env.state = state
    for name in ("min_position", "max_position", "goal_position"):
        value = getattr(scene, name, None)
        if value is not None:
            setattr(gym_env, name, _float(value))


_CLASSIC = "gymnasium.envs.classic_control"

SPECS: dict[str, GymSpec] = {
    spec.id: spec
    for spec in (
        GymSpec(
            name="CartPole-v1",
            scene="CartPole",
            max_episode_steps=500,
            reward_threshold=475.0,
            initial_state=_uniform(-0.05, 0.05, 4),
            renderer=f"{_CLASSIC}.cartpole:CartPoleEnv",
            render_sync=_sync_cartpole,
        ),
        GymSpec(
            name="Pendulum-v1",
            scene="Pendulum",
            max_episode_steps=200,
            reward_threshold=None,
            initial_state=_pendulum_initial_state,
            renderer=f"{_CLASSIC}.pendulum:PendulumEnv",
            render_sync=_sync_pendulum,
        ),
        GymSpec(
            name="Acrobot-v1",
            scene="Acrobot",
            max_episode_steps=500,
            reward_threshold=-100.0,
            initial_state=_uniform(-0.1, 0.1, 4, round_to_float32=True),
            renderer=f"{_CLASSIC}.acrobot:AcrobotEnv",
            render_sync=_sync_acrobot,
        ),
        GymSpec(
            name="MountainCar-v0",
            scene="MountainCar",
            max_episode_steps=200,
            reward_threshold=-110.0,
            initial_state=_mountain_car_initial_state,
            renderer=f"{_CLASSIC}.mountain_car:MountainCarEnv",
            render_sync=_sync_mountain_car,
        ),
        GymSpec(
            name="MountainCarContinuous-v0",
            scene="MountainCarContinuous",
            max_episode_steps=999,
            reward_threshold=90.0,
            initial_state=_mountain_car_initial_state,
            renderer=f"{_CLASSIC}.continuous_mountain_car:Continuous_MountainCarEnv",
            render_sync=_sync_mountain_car,
        ),
    )
}
"""All ids the layer knows, by id. Only those whose scene exists are registered."""
