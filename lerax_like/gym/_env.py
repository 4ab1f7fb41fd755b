"""`GymnasiumEnv`: a scene behind Gymnasium's `Env` interface, stepping as Gymnasium's env does."""

from typing import Any, SupportsFloat

import gymnasium
import jax
import numpy as np

from . import _render
from ._compiled import HoldsScene, build_scene, float64, pack_step
from ._spaces import to_gymnasium_space
from ._specs import GymSpec


class GymnasiumEnv(HoldsScene, gymnasium.Env):
    """A lerax_like scene as a Gymnasium env (what `gymnasium.make("lerax_like/<id>")` builds).

    Behaves as Gymnasium's own env of the same name:

    - `reset(seed=s, options=...)` draws the initial state through `self.np_random` with
      the same calls as Gymnasium's env, so the same seed gives the same initial state;
    - `step` returns a float32 observation, a Python float reward and Python bool
      `terminated`/`truncated` (always False here: the time limit is the `TimeLimit`
      wrapper `gymnasium.make` adds, as for Gymnasium's envs);
    - `state` is the float64 state in Gymnasium's layout, readable and writable (for
      model-predictive control, parity tests);
    - invalid discrete actions are refused with Gymnasium's `AssertionError`; a continuous
      action must have one element and is clipped by the scene.

    The step is the scene's `transition` integrated in float64 (a `jax.enable_x64` scope
    around every call, no global switch) with the scene's solver; the keywords of
    `gymnasium.make` (`solver="rk4"`, `stepsize_controller`, physical parameters) go to
    the scene. The info holds the integrator's `solver_ok` and `solver_steps`; a failed
    solve keeps the pre-step state and terminates the episode.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    def __init__(self, spec: GymSpec, render_mode: str | None = None, **scene_kwargs: Any):
        self._gym_spec = spec
        self.scene = build_scene(spec.scene, scene_kwargs)
        with float64():
            self.action_space = to_gymnasium_space(self.scene.action_space)
            self.observation_space = to_gymnasium_space(self.scene.observation_space)
        self._observation_size = int(np.prod(self.observation_space.shape))
        self.metadata = {**self.metadata, "render_fps": _render.render_fps(spec)}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = None
        self._state: np.ndarray | None = None
        self._steps = 0
        self._last_action: np.ndarray | None = None
        self._warm_up()

    @property
    def state(self) -> np.ndarray | None:
        """The state, float64 in Gymnasium's layout (None before the first reset)."""
        return self._state

    @state.setter
    def state(self, value) -> None:
        if value is None:
            self._state = None
            return
        expected = self._initial_bounds[0].shape
        try:
            state = np.array(value, dtype=np.float64)
        except (TypeError, ValueError) as error:
            raise TypeError(f"state must be a real array of shape {expected}, got {value!r}") from error
        if state.shape != expected:
            raise ValueError(f"state must have shape {expected} ({self._gym_spec.name}'s state), got shape {state.shape}")
        self._state = state

    def _warm_up(self) -> None:
        # Compile the step and the observation now, not in the first step of training.
        # A state drawn as reset draws it, from a generator of its own (np_random untouched).
        y = self._gym_spec.initial_state(self._initial_bounds, np.random.default_rng(0), None, 1)[:, 0]
        action = self._action(self._zero_action())
        with float64():
            jax.block_until_ready(self._split.step(self._split.parameters, pack_step(y, 0, action), self._jax_key))
            jax.block_until_ready(self._split.observe(self._split.parameters, y, np.int64(0), self._jax_key))

    def _zero_action(self):
        if isinstance(self.action_space, gymnasium.spaces.Discrete):
            return np.int64(self.action_space.start)
        return np.zeros(self.action_space.shape, dtype=np.float32)

    def _action(self, action) -> np.ndarray:
        if isinstance(self.action_space, gymnasium.spaces.Discrete):
            # `self.action_space.contains(action)`, which Gymnasium's CartPole asserts, in
            # half its time: an integer, or an integer array of shape (), in range.
            integer = isinstance(action, int) or (
                isinstance(action, (np.generic, np.ndarray)) and action.dtype.kind in "iu" and action.shape == ()
            )
            start = self.action_space.start
            assert integer and start <= action < start + self.action_space.n, f"{action!r} ({type(action)}) invalid"
            return np.int64(action)
        array = np.asarray(action, dtype=np.float64)
        if array.size != self.action_space.shape[0] or array.ndim > 1:
            raise ValueError(f"the action must have shape {self.action_space.shape} ({self.action_space}), got {action!r}")
        return array.reshape(self.action_space.shape)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._jax_key = self._split.key(seed)
        self.state = self._gym_spec.initial_state(self._initial_bounds, self.np_random, options, 1)[:, 0]
        self._steps = 0
        self._last_action = None
        with float64():
            observation, self._jax_key = self._split.observe(
                self._split.parameters, self._state, np.int64(0), self._jax_key
            )
            observation = np.array(observation)
        if self.render_mode == "human":
            self.render()
        return observation, {}

    def step(self, action) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        action = self._action(action)
        assert self._state is not None, "Call reset before using step method."
        with float64():
            outcome, self._jax_key = self._split.step(
                self._split.parameters, pack_step(self._state, self._steps, action), self._jax_key
            )
        # np.asarray, not jax.device_get: the latter costs far more for arrays this small.
        outcome = np.asarray(outcome)
        n, m = self._state.shape[0], self._observation_size
        # The observation was computed in float32; the float64 round trip is exact.
        observation = outcome[n : n + m].astype(np.float32)
        reward, terminated, solver_ok, solver_steps = outcome[n + m :].tolist()
        self._state = outcome[:n].copy()
        self._steps += 1
        self._last_action = action
        if self.render_mode == "human":
            self.render()
        info = {"solver_ok": bool(solver_ok), "solver_steps": int(solver_steps)}
        return observation, float(reward), bool(terminated), False, info

    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, "
                f'e.g. gym.make("{self._gym_spec.id}", render_mode="rgb_array")'
            )
            return None
        if self._state is None:
            return None
        if self._renderer is None:
            self._renderer = _render.make_renderer(self._gym_spec, self.render_mode)
        return _render.draw(self._renderer, self._gym_spec, self.scene, self._state, self._last_action)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


__all__ = ["GymnasiumEnv"]
