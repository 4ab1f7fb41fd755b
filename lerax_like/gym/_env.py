"""`GymnasiumEnv`: a scene behind Gymnasium's `Env` interface, stepping as Gymnasium's env does."""

import math
from typing import Any, SupportsFloat

import gymnasium
import jax
import numpy as np

from ..env import AbstractEnv
from . import _render
from ._attributes import GymnasiumAttributes
from ._inputs import check_action, check_state
from ._compiled import SplitScene, build_scene, float64, pack_step, to_device, to_host, to_numpy, unpack_step
from ._spaces import to_gymnasium_space
from ._specs import GymSpec


class GymnasiumEnv(GymnasiumAttributes, gymnasium.Env):
    """A lerax_like scene as a Gymnasium env (what `gymnasium.make("lerax_like/<id>")` builds).

    Behaves as Gymnasium's own env of the same name:

    - `reset(seed=s, options=...)` draws the initial state through `self.np_random` with
      the same calls as Gymnasium's env, so the same seed gives the same initial state;
    - `step` returns a float32 observation, a Python float reward and Python bool
      `terminated`/`truncated` (always False here: the time limit is the `TimeLimit`
      wrapper `gymnasium.make` adds, as for Gymnasium's envs);
    - `state` is the float64 state in Gymnasium's layout, readable and writable (for
      model-predictive control, parity tests), and must be finite;
    - an action that cannot be applied (a discrete one out of range or not an integer, a
      non-finite continuous one) is refused with a `ValueError` naming it and the space
      (Gymnasium's envs `assert`, which `python -O` drops); a continuous action must have
      one element and is clipped by the scene.

    A thin sibling of the vector env's `Batch`: one env, its host state (writable in
    place, as Gymnasium's) and one compiled call per step that takes the action, the step
    count and the state packed in one array.

    The step is the scene's `transition` integrated in float64 (a `jax.enable_x64` scope
    around every call, no global switch) with the scene's solver; the keywords of
    `gymnasium.make` (`solver="rk4"`, `stepsize_controller`, physical parameters) go to
    the scene. The info holds the integrator's `solver_ok` and `solver_steps`, and
    `action_ok`; a failed solve keeps the pre-step state and terminates the episode.

    It has Gymnasium's attributes of the id's env (`masspole`, `tau`, ...), readable and
    writable (`GymnasiumAttributes`).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 50}
    # What `to_gymnasium_space` builds (Gymnasium declares any `Space`).
    action_space: gymnasium.spaces.Discrete | gymnasium.spaces.Box
    observation_space: gymnasium.spaces.Discrete | gymnasium.spaces.Box

    def __init__(self, spec: GymSpec, render_mode: str | None = None, **scene_kwargs: Any):
        self._gym_spec = spec
        self._jax_key = None
        self.scene = build_scene(spec.scene, scene_kwargs)
        with float64():
            self.action_space = to_gymnasium_space(self.scene.action_space)
            observation_space = self.scene.observation_space
            self.observation_space = to_gymnasium_space(observation_space)
        self._observation_size = math.prod(observation_space.shape)
        self.metadata = {**self.metadata, "render_fps": _render.render_fps(spec)}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = None
        self._state: np.ndarray | None = None
        self._steps = 0
        self._last_action: np.ndarray | np.int64 | None = None
        self._warm_up()

    @property
    def scene(self) -> AbstractEnv:
        """The functional env behind the wrapper. Assign a modified scene to change parameters."""
        return self._split.scene

    @scene.setter
    def scene(self, scene: AbstractEnv) -> None:
        self._split = SplitScene(scene)
        self._jax_key = self._split.carried_key(self._jax_key)
        with float64():
            self._initial_bounds = tuple(np.array(bound, dtype=np.float64) for bound in scene.initial_bounds)

    @property
    def split(self) -> SplitScene:
        """The scene split into packed parameters and its compiled functions (`split.compiled.step`)."""
        return self._split

    @property
    def state(self) -> np.ndarray | None:
        """The state, float64 in Gymnasium's layout (None before the first reset)."""
        return self._state

    @state.setter
    def state(self, value) -> None:
        self._state = None if value is None else check_state(
            value, self._initial_bounds[0].shape, "float64", f"{self._gym_spec.name}'s state"
        )

    def _warm_up(self) -> None:
        # Compile the step and the observation now, not in the first step of training.
        # A state drawn as reset draws it, from a generator of its own (np_random untouched).
        y = self._gym_spec.initial_state(self._initial_bounds, np.random.default_rng(0), None, 1)[:, 0]
        if isinstance(self.action_space, gymnasium.spaces.Discrete):
            action = np.int64(self.action_space.start)
        else:
            action = np.zeros(self.action_space.shape, dtype=np.float64)
        compiled, parameters = self._split.compiled, self._split.parameters
        with float64():
            jax.block_until_ready(compiled.step(parameters, pack_step(y, 0, action), self._jax_key))
            jax.block_until_ready(compiled.observe(parameters, y, np.int64(0), self._jax_key))

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._jax_key = self._split.key(seed)
        self.state = self._gym_spec.initial_state(self._initial_bounds, self.np_random, options, 1)[:, 0]
        self._steps = 0
        self._last_action = None
        with float64():
            observation, self._jax_key = self._split.compiled.observe(
                self._split.parameters, self._state, np.int64(0), self._jax_key
            )
            observation = to_numpy(observation)
        if self.render_mode == "human":
            self.render()
        return observation, {}

    def step(self, action) -> tuple[np.ndarray, SupportsFloat, bool, bool, dict[str, Any]]:
        action = check_action(self.action_space, action)
        if self._state is None:
            raise RuntimeError("Call reset before using step method.")
        with float64():
            outcome, self._jax_key = self._split.compiled.step(
                self._split.parameters, pack_step(self._state, self._steps, action), self._jax_key
            )
        # `to_numpy`, not jax.device_get: the latter costs far more for arrays this small.
        outcome = unpack_step(to_numpy(outcome), self._state.shape[0], self._observation_size)
        self._state = outcome.state
        self._steps += 1
        self._last_action = action
        if self.render_mode == "human":
            self.render()
        info = {"solver_ok": outcome.solver_ok, "solver_steps": outcome.solver_steps, "action_ok": outcome.action_ok}
        return outcome.observation, outcome.reward, outcome.terminated, False, info

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
        return self._renderer.draw(self.scene, self._state, self._last_action)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # Pickling (to save, checkpoint, or ship an env to a worker process): the compiled
    # functions and the renderer are dropped, and JAX arrays (the scene's leaves, the key)
    # travel as NumPy arrays, so that a process without float64 enabled loads them in
    # float64. On load the scene is split again: its functions come from the cache when
    # this process compiled them already. Everything else (the NumPy generator included)
    # is copied, so a loaded copy continues exactly as the original.

    def __getstate__(self) -> dict[str, Any]:
        state = {name: value for name, value in self.__dict__.items() if name not in ("_split", "_renderer")}
        return to_host({**state, "_scene": self.scene})

    def __setstate__(self, state: dict[str, Any]) -> None:
        state = to_device(state)
        self._split = SplitScene(state.pop("_scene"))
        self.__dict__.update(state, _renderer=None)
