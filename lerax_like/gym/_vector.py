"""`GymnasiumVectorEnv`: many copies of a scene stepped by one compiled, batched step."""

from typing import Any

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _render
from ._compiled import HoldsScene, build_scene, check_dtype, float64
from ._spaces import to_gymnasium_space
from ._specs import GymSpec


class GymnasiumVectorEnv(HoldsScene, VectorEnv):
    """`num_envs` copies of a scene (what `gymnasium.make_vec("lerax_like/<id>", N,
    vectorization_mode="vector_entry_point")` builds).

    One call of `step` is one compiled, batched step of all envs, integrated in `dtype`.
    It follows Gymnasium's next-step autoreset, as Gymnasium's vector CartPole does: the
    step after an episode ends (terminated, or truncated after `max_episode_steps`)
    restarts that env, returning its fresh observation, reward 0 and terminated and
    truncated False. Initial states are drawn on the host from `self.np_random` with the
    calls of Gymnasium's vector CartPole (`uniform(size=(4, num_envs))` at reset, one
    draw of shape `(4, number of ended envs)` at a step that restarts some), and only at
    such steps; so for CartPole the same seed and actions give Gymnasium's numbers.

    `dtype` is the precision of the step: `"float64"` (the default) computes as Gymnasium
    does, `"float32"` as JAX users run on accelerators (the parameters are cast once; the
    starts are drawn as above, then rounded). Observations are float32 either way.

    `state` is the state in the layout of Gymnasium's vector CartPole (`(n, num_envs)`,
    of `dtype`), readable and writable. The info holds the per-env `solver_ok` and
    `solver_steps`, with Gymnasium's `_name` masks. Rewards are of `dtype`.

    Stepped from Python on a CPU, each step waits for JAX's dispatch thread; with
    `jax.config.update("jax_cpu_enable_async_dispatch", False)`, called before JAX's first
    computation, it runs in the calling thread: 1.2-2.1x faster in float64 at 1024 envs on
    a 2-core machine (`benchmarks/results/gym_vector.csv`).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        spec: GymSpec,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        dtype: str = "float64",
        **scene_kwargs: Any,
    ):
        self._dtype = check_dtype(dtype)
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        if max_episode_steps is not None and (not isinstance(max_episode_steps, int) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or an integer >= 1, got {max_episode_steps!r}")
        self._gym_spec = spec
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        scene = build_scene(spec.scene, scene_kwargs)
        self.scene = scene
        with float64():
            self.single_action_space = to_gymnasium_space(scene.action_space)
            self.single_observation_space = to_gymnasium_space(scene.observation_space)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.metadata = {**self.metadata, "render_fps": _render.render_fps(spec)}
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = None
        self._discrete = isinstance(self.single_action_space, gymnasium.spaces.Discrete)
        self._options: dict[str, Any] | None = None
        self._y: jax.Array | None = None
        self._steps: jax.Array | None = None
        self._prev_done = np.zeros(num_envs, dtype=np.bool_)
        self._last_action: np.ndarray | None = None
        self._info_mask = np.ones(num_envs, dtype=np.bool_)
        self._reset_y: np.ndarray | None = None
        self._observation: jax.Array | None = None  # the last one returned, on the device
        self._warm_up()

    @property
    def dtype(self) -> str:
        """The precision of the step: `"float64"` or `"float32"`."""
        return self._dtype

    @property
    def state(self) -> np.ndarray | None:
        """The states, of `dtype`, shape `(n, num_envs)` (Gymnasium's vector CartPole layout)."""
        return None if self._y is None else np.array(self._y).T

    @state.setter
    def state(self, value) -> None:
        value = np.asarray(value, dtype=self._dtype)
        expected = (self._initial_bounds[0].size, self.num_envs)
        if value.shape != expected:
            raise ValueError(f"state must have shape {expected} (state size, num_envs), got shape {value.shape}")
        with self._split.precision():
            self._y = jnp.asarray(value.T)
            if self._steps is None:
                self._steps = jnp.zeros(self.num_envs, dtype=int)
        self._observation = None  # of the old state: the next step observes the new one

    def _warm_up(self) -> None:
        # Compile the step and the observation now, not in the first step of training.
        y = self._starts(np.random.default_rng(0), None, self.num_envs)
        self._reset_y = np.zeros_like(y)
        with self._split.precision():
            self._no_reset = jnp.zeros(self.num_envs, dtype=bool)
            no_limit = np.iinfo(jnp.zeros((), dtype=int).dtype).max
            self._time_limit = jnp.asarray(no_limit if self.max_episode_steps is None else self.max_episode_steps)
            steps = jnp.zeros(self.num_envs, dtype=int)
            parameters, key = self._split.parameters, self._jax_key
            actions = self._actions(self._zero_actions())
            observation, _ = self._split.vector_observe(parameters, y, steps, key)
            arguments = (parameters, y, steps, actions, key)
            jax.block_until_ready(self._split.vector_advance(*arguments, self._time_limit, observation))
            jax.block_until_ready(
                self._split.vector_step(*arguments, self._no_reset, y, self._time_limit, observation)
            )

    def _starts(self, np_random, options, count: int) -> np.ndarray:
        """`count` starts drawn as Gymnasium draws them, shape `(count, n)`, of `dtype`."""
        starts = self._gym_spec.initial_state(self._initial_bounds, np_random, options, count).T
        return starts.astype(self._dtype, copy=False)

    def _zero_actions(self):
        if self._discrete:
            return np.full(self.num_envs, self.single_action_space.start, dtype=np.int64)
        return np.zeros((self.num_envs, *self.single_action_space.shape), dtype=np.float32)

    def _actions(self, actions) -> np.ndarray:
        if self._discrete:
            # `self.action_space.contains(actions)`, which Gymnasium's vector CartPole
            # asserts, in a third of its time.
            array = np.asarray(actions)
            start, n = self.single_action_space.start, self.single_action_space.n
            valid = (
                array.shape == (self.num_envs,)
                and array.dtype.kind in "iu"
                and array.min() >= start
                and array.max() < start + n
            )
            assert valid, f"{actions!r} ({type(actions)}) invalid"
            return array.astype(np.int64, copy=False)
        array = np.asarray(actions, dtype=self._dtype)
        shape = (self.num_envs, *self.single_action_space.shape)
        if array.size != np.prod(shape):
            raise ValueError(f"the actions must have shape {shape}, got an array of shape {array.shape}")
        return array.reshape(shape)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self._jax_key = self._split.key(seed)
        self._options = options
        y = self._starts(self.np_random, options, self.num_envs)
        with self._split.precision():
            self._y = jnp.asarray(y)
            self._steps = jnp.zeros(self.num_envs, dtype=int)
            self._observation, self._jax_key = self._split.vector_observe(
                self._split.parameters, self._y, self._steps, self._jax_key
            )
            observation = np.array(self._observation)
        self._prev_done = np.zeros(self.num_envs, dtype=np.bool_)
        self._last_action = None
        return observation, {}

    def step(self, actions):
        actions = self._actions(actions)
        assert self._y is not None, "Call reset before using step method."
        split = self._split
        with split.precision():
            if self._observation is None:  # the state or the scene was assigned
                self._observation, self._jax_key = split.vector_observe(
                    split.parameters, self._y, self._steps, self._jax_key
                )
            restarts = np.count_nonzero(self._prev_done)
            if restarts:
                # Gymnasium's vector CartPole draws only when some env restarts, for those
                # envs. The rows of the other envs in `_reset_y` are stale and unused.
                reset_mask = self._prev_done
                self._reset_y[reset_mask] = self._starts(self.np_random, self._options, restarts)
                outputs = split.vector_step(
                    split.parameters, self._y, self._steps, actions, self._jax_key, reset_mask, self._reset_y,
                    self._time_limit, self._observation,
                )
            else:
                # No restart: the step without the restart's selects and fresh observations.
                outputs = split.vector_advance(
                    split.parameters, self._y, self._steps, actions, self._jax_key, self._time_limit,
                    self._observation,
                )
        self._y, self._steps, observation, outcome, self._jax_key = outputs
        self._observation = observation
        # np.array (a writable copy) of the observation, not jax.device_get: the latter
        # costs far more for arrays this small. Every result below is a new array.
        observation, outcome = np.array(observation), np.asarray(outcome)
        terminated, truncated, solver_ok = outcome[1:4] != 0
        self._prev_done = terminated | truncated
        self._last_action = actions
        info = {
            "solver_ok": solver_ok,
            "_solver_ok": self._info_mask.copy(),
            "solver_steps": outcome[4].astype(np.int64),
            "_solver_steps": self._info_mask.copy(),
        }
        return observation, outcome[0].copy(), terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gymnasium.logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, "
                f'e.g. gym.make_vec("{self._gym_spec.id}", render_mode="rgb_array")'
            )
            return None
        states = self.state
        if states is None:
            raise ValueError("the state is None: call reset before render")
        if self._renderer is None:
            self._renderer = _render.make_renderer(self._gym_spec, self.render_mode)
        actions = [None] * self.num_envs if self._last_action is None else list(self._last_action)
        return [
            _render.draw(self._renderer, self._gym_spec, self.scene, state, action)
            for state, action in zip(states.T, actions, strict=True)
        ]

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


__all__ = ["GymnasiumVectorEnv"]
