"""`CompiledVecEnv`: an SB3 `VecEnv` whose step is the vector env's compiled, batched step."""

import os
from collections.abc import Sequence
from typing import Any

import gymnasium
import jax
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from ..gym import SPECS, GymSpec, GymnasiumVectorEnv
from ..gym._attributes import GymnasiumAttributes
from ..gym._inputs import check_actions


class EnvView(GymnasiumAttributes):
    """Env `index` of a `CompiledVecEnv`, as `DummyVecEnv`'s `get_attr`, `set_attr` and
    `env_method` see its single env (the `Monitor` over `gymnasium.make(env_id)`).

    It has Gymnasium's attributes of the id (`masspole`, `goal_velocity`, ...:
    `GymnasiumAttributes`), read from this env's scene and written to it alone: a write
    changes this env's physics from its next step on. `scene` is this env's scene,
    `state` its state, `np_random` its generator, `render()` its frame (`rgb_array`) or the
    window of all envs (`human`); `get_wrapper_attr`, `set_wrapper_attr` and
    `has_wrapper_attr` are Gymnasium's. Other names read the vector env's shared
    attributes (`render_mode`, `max_episode_steps`, `dtype`); a name written that the env
    does not have is kept on this view, as `DummyVecEnv` keeps it on the wrapper.
    """

    def __init__(self, venv: "CompiledVecEnv", index: int, spec: GymSpec):
        self._venv = venv
        self._index = index
        self._gym_spec = spec

    @property
    def scene(self):
        return self._venv.batch.scene_at(self._index)

    @scene.setter
    def scene(self, scene) -> None:
        self._venv.batch.set_scenes([self._index], [scene])

    @property
    def state(self) -> np.ndarray | None:
        state = self._venv.batch.state
        return None if state is None else state[self._index]

    @property
    def np_random(self) -> np.random.Generator | None:
        return self._venv.generators[self._index]

    @property
    def spec(self):
        return self._venv.spec

    @property
    def unwrapped(self) -> "EnvView":
        return self

    @property
    def observation_space(self):
        return self._venv.observation_space

    @property
    def action_space(self):
        return self._venv.action_space

    def render(self):
        vector = self._venv.vector
        if vector.render_mode == "human":
            return self._venv.render()
        if vector.render_mode is None:
            return None
        return vector.frame(self._index)

    def get_wrapper_attr(self, name: str) -> Any:
        return getattr(self, name)

    def has_wrapper_attr(self, name: str) -> bool:
        return hasattr(self, name)

    def set_wrapper_attr(self, name: str, value: Any, *, force: bool = True) -> bool:
        if force or hasattr(self, name):
            setattr(self, name, value)
            return True
        return False

    def __getattr__(self, name: str) -> Any:
        # Only for names this class and its instance lack: Gymnasium's attributes of the id,
        # then the vector env's shared ones. Private names are not forwarded (a view being
        # unpickled has no `_venv` yet).
        try:
            return super().__getattr__(name)
        except AttributeError:
            if name.startswith("_"):
                raise
            return getattr(self._venv.vector, name)


def inline_cpu_dispatch() -> None:
    """Make JAX run its CPU computations in the calling thread, for the whole process, if
    JAX has not started its CPU client yet.

    JAX reads `jax_cpu_enable_async_dispatch` once, when it starts the client (`import
    lerax_like` does not start it). Once started with asynchronous dispatch, the client
    keeps it, and this changes nothing: the flag is left as it is rather than set to a
    value the client does not follow.
    """
    from jax._src import xla_bridge  # JAX has no public way to ask whether its client has started

    started = getattr(xla_bridge, "backends_are_initialized", lambda: True)()
    if not started:
        jax.config.update("jax_cpu_enable_async_dispatch", False)


class CompiledVecEnv(VecEnv):
    """`num_envs` copies of a registered id behind SB3's `VecEnv` interface, stepped as one batch.

    Steps as SB3's `DummyVecEnv` of `gymnasium.make(env_id)` envs does, with the numbers
    of `lerax_like`'s single env (`AbstractEnv.advance` in float64):

    - same-step autoreset: when an episode ends (terminated, or truncated after
      `max_episode_steps`, Gymnasium's `TimeLimit`), `done` is True, the returned
      observation is the next episode's first, and the info holds the last one under
      `"terminal_observation"`;
    - `info["TimeLimit.truncated"]` is `truncated and not terminated`; the info also
      holds the step's `solver_ok`, `solver_steps` and `action_ok`, as the single env's;
    - each env has its own NumPy generator, seeded at a reset with SB3's seeds (`seed(s)`
      gives env `i` the seed `s + i` at the next reset), from which its starts are drawn
      with the calls of Gymnasium's env: the same seeds give `DummyVecEnv`'s starts;
    - rewards are float32 and observations float32, as `DummyVecEnv` returns them.

    One step is one compiled call of all envs, restarts included (`Batch.advance_then_restart`):
    each env's next start is drawn from its generator on the host when its episode starts,
    so the step that ends the episode restarts the env at once (until the generators are
    handed out: `generators`). Actions that cannot be applied are refused with a
    `ValueError` naming them, and nothing steps.

    `get_attr`, `set_attr` and `env_method` act on each env's `EnvView`, as `DummyVecEnv`'s
    act on each env: `set_attr("masspole", 0.2, indices=[1])` changes env 1's physics alone
    (one parameter row per env, still one compiled call), where `DummyVecEnv`'s stops at
    the outer `Monitor` (docs/gymnasium.md).

    `render_mode` is None, `"rgb_array"` (SB3's `render()` tiles the envs' frames) or
    `"human"` (every reset and step shows the envs, tiled in one pygame window).

    `inline_dispatch` (True by default) calls `inline_cpu_dispatch` first: what makes the
    VecEnv as fast as SB3's `DummyVecEnv` at 8 envs (docs/performance.md); it changes no
    number, and False leaves JAX's setting as it is.
    """

    # The vector env's single action space, as `to_gymnasium_space` builds it (SB3 declares any `Space`).
    action_space: gymnasium.spaces.Discrete | gymnasium.spaces.Box

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        *,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        dtype: str = "float64",
        inline_dispatch: bool = True,
        **scene_kwargs: Any,
    ):
        if not isinstance(inline_dispatch, bool):
            raise ValueError(f"inline_dispatch must be True or False, got {inline_dispatch!r}")
        if inline_dispatch:  # before anything starts JAX's CPU client
            inline_cpu_dispatch()
        if env_id not in SPECS:
            raise ValueError(f"env_id must be one of {tuple(SPECS)}, got {env_id!r}")
        if render_mode not in _RENDER_MODES:
            raise ValueError(f"render_mode must be one of {_RENDER_MODES}, got {render_mode!r}")
        spec = SPECS[env_id]
        if max_episode_steps is None:
            max_episode_steps = spec.max_episode_steps
        # The vector env holds the batch, the spaces, the renderer and the attributes; its
        # own autoreset is not used: this env restarts in its step, through the batch.
        self._vector = GymnasiumVectorEnv(
            spec, num_envs=num_envs, max_episode_steps=max_episode_steps, render_mode=render_mode, dtype=dtype,
            autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP, warm_up=False, **scene_kwargs,
        )
        self._vector.warm_up_moves(advance=False, advance_then_restart=True)
        self._batch = self._vector.batch
        self.spec = gymnasium.spec(env_id)
        self.max_episode_steps = max_episode_steps
        self._generators: list[np.random.Generator | None] = [None] * num_envs
        # Each env's next start, drawn ahead (`_draw_ahead`), with a copy on the device, and its
        # generator's state before that draw; None once the generators are handed out (`generators`).
        self._next_starts: np.ndarray | None = np.zeros(
            (num_envs, self._batch.initial_bounds[0].size), dtype=self._batch.dtype
        )
        self._next_starts_on_device: jax.Array | None = None
        self._drawn_from: list[dict[str, Any] | None] = [None] * num_envs
        self._actions: np.ndarray | None = None
        # The actions a step takes without a check on the host (the step checks them, `step_wait`):
        # those of the dtype and shape it computes with. In float32, JAX would wrap int64 actions
        # to int32 before the step saw them, so those are checked on the host.
        action_space = self._vector.single_action_space
        if isinstance(action_space, gymnasium.spaces.Discrete):
            self._unchecked = (np.dtype(np.int64), (num_envs,)) if dtype == "float64" else None
        else:
            self._unchecked = (np.dtype(dtype), (num_envs, *action_space.shape))
        self._views = [EnvView(self, index, spec) for index in range(num_envs)]
        super().__init__(num_envs, self._vector.single_observation_space, self._vector.single_action_space)

    # -- SB3's VecEnv ------------------------------------------------------------------

    def reset(self):
        self._undraw()
        for index, seed in enumerate(self._seeds):
            if seed is not None or self._generators[index] is None:
                self._generators[index], _ = seeding.np_random(seed)
        if self._seeds[0] is not None:
            self._batch.seed(self._seeds[0])
        observation = self._batch.reset(self._starts(range(self.num_envs)))
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        self._vector.last_action = None
        if self._next_starts is not None:
            self._draw_ahead(range(self.num_envs))
        if self.render_mode == "human":
            self._vector.show()
        return observation

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        actions = self._actions
        unchecked = self._unchecked
        if unchecked is None or type(actions) is not np.ndarray or (actions.dtype, actions.shape) != unchecked:
            actions = check_actions(self.action_space, actions, self.num_envs, self._batch.dtype)
        step = self._batch.advance_then_restart(actions, self._next_starts_on_device)
        if not step.admissible:  # nothing has changed
            check_actions(self.action_space, actions, self.num_envs, self._batch.dtype)  # names the action
            raise ValueError(f"the actions {actions!r} cannot all be applied in {self.action_space}")
        observation = step.observation
        # `action_ok` is True for every env: a step with an inadmissible action is refused above.
        infos = [
            {"solver_ok": ok, "solver_steps": steps, "action_ok": True, "TimeLimit.truncated": limit}
            for ok, steps, limit in zip(step.solver_ok, step.solver_steps, step.time_limit)
        ]
        ended = np.flatnonzero(step.done)
        if ended.size:
            for index in ended:
                infos[index]["terminal_observation"] = step.final_observation[index].copy()
            if self._next_starts is not None:  # they restarted in the step, from the starts drawn ahead
                self._draw_ahead(ended)
            else:
                fresh = self._batch.restart(step.done, self._autoreset_starts(ended.tolist()))
                observation[ended] = fresh[ended]
        self._vector.last_action = actions
        if self.render_mode == "human":
            self._vector.show()
        return observation, step.reward, step.done, infos

    # An env's next start is drawn from its generator when its episode starts, not when it
    # ends: then the step that ends it restarts it in the same compiled call. Each generator
    # draws only starts, so it draws the same numbers in the same order as `DummyVecEnv`'s
    # env draws them at its reset. Its state before the draw is kept, and put back before
    # anything else may draw from it: a reset, or handing the generators out.

    def _draw_ahead(self, indices) -> None:
        next_starts = self._next_starts
        if next_starts is None:  # the generators are handed out: each start is drawn at its restart
            return
        indices = list(indices)
        for index in indices:
            if (generator := self._generators[index]) is not None:
                self._drawn_from[index] = generator.bit_generator.state
        next_starts[indices] = self._autoreset_starts(indices)
        self._next_starts_on_device = self._batch.device_copy(next_starts)

    def _undraw(self) -> None:
        for index, state in enumerate(self._drawn_from):
            if state is not None and (generator := self._generators[index]) is not None:
                generator.bit_generator.state = state
        self._drawn_from = [None] * self.num_envs

    def _autoreset_starts(self, indices: list[int]) -> np.ndarray:
        """A start for each env of `indices` (reset already), drawn from its generator as the
        autoreset of `DummyVecEnv`'s env draws it: without options."""
        generators = [generator for index in indices if (generator := self._generators[index]) is not None]
        return self._vector.starts_each(generators, [None] * len(generators))

    # Pickling: the device copy of the starts drawn ahead is made again on load, in the
    # batch's dtype (a JAX array would load in the loading process's precision).

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_next_starts_on_device": None}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            object.__setattr__(self, name, value)
        if self._next_starts is not None and self._batch.state is not None:
            self._next_starts_on_device = self._batch.device_copy(self._next_starts)

    def _starts(self, indices) -> np.ndarray:
        """Starts of the envs `indices`, each drawn from its own generator as Gymnasium's env draws it."""
        return self._vector.starts_each(
            [self._generators[index] for index in indices], [self._options[index] or None for index in indices]
        )

    def close(self) -> None:
        self._vector.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        # In rgb_array mode the vector env returns one frame per env, never None.
        if self.render_mode != "rgb_array" or (frames := self._vector.render()) is None:
            return [None] * self.num_envs
        return frames

    def render(self, mode: str | None = None):
        if self.render_mode == "human" and mode in (None, "human"):
            # SB3's VecEnv.render would call every env's render: one window shows them all.
            self._vector.show()
            return None
        return super().render(mode)

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [self._views[index].get_wrapper_attr(attr_name) for index in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for index in self._indices(indices):
            setattr(self._views[index], attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        return [
            self._views[index].get_wrapper_attr(method_name)(*method_args, **method_kwargs)
            for index in self._indices(indices)
        ]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        # No Gymnasium wrapper is around the envs; `make_vec_env`'s monitor answers for `Monitor`.
        return [False] * len(self._indices(indices))

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        indices = [indices] if isinstance(indices, (int, np.integer)) else list(indices)
        for index in indices:
            if not isinstance(index, (int, np.integer)) or not -self.num_envs <= index < self.num_envs:
                raise IndexError(f"indices must be env indices in [0, {self.num_envs}), got {index!r}")
        return [int(index) % self.num_envs for index in indices]

    # -- what the views reach --------------------------------------------------------------

    @property
    def batch(self):
        """The `Batch` the envs step in (`batch.scene_at(i)`: env `i`'s scene)."""
        return self._batch

    @property
    def vector(self) -> GymnasiumVectorEnv:
        """The Gymnasium vector env behind this one: spaces, renderer, shared attributes."""
        return self._vector

    @property
    def generators(self) -> list[np.random.Generator | None]:
        """Each env's NumPy generator, from which its starts are drawn.

        Once they are handed out, anyone may draw from them, so from then on each env's
        start is drawn when it restarts (not ahead), and a restart is a second compiled
        call: the numbers stay `DummyVecEnv`'s."""
        if self._next_starts is not None:
            self._undraw()
            self._next_starts = self._next_starts_on_device = None
        return self._generators

    # -- the scene, as the vector env shows it -----------------------------------------

    @property
    def scene(self):
        """The functional env all copies share. Assign a modified scene to change parameters."""
        return self._vector.scene

    @scene.setter
    def scene(self, scene) -> None:
        self._vector.scene = scene

    @property
    def state(self) -> np.ndarray | None:
        """The states, shape `(n, num_envs)`, as `GymnasiumVectorEnv.state`."""
        return self._vector.state


_RENDER_MODES = (None, "human", "rgb_array")


class MonitoredVecEnv(VecMonitor):
    """SB3's `VecMonitor`, which is what `make_vec_env` monitors with, answering
    `env_is_wrapped(Monitor)` with True for every env as `DummyVecEnv` of `Monitor`-wrapped
    envs does: its episode statistics (`info["episode"]`) are `Monitor`'s. So SB3 knows the
    envs are monitored (`evaluate_policy` reads the episodes from it), and a `VecMonitor`
    put over it warns, as SB3 warns over its own monitored envs, instead of recording every
    episode a second time unannounced."""

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        if issubclass(Monitor, wrapper_class):
            if indices is None:
                count = self.num_envs
            elif isinstance(indices, (int, np.integer)) or (isinstance(indices, np.ndarray) and indices.ndim == 0):
                count = 1
            else:
                count = len(list(indices))
            return [True] * count
        return self.venv.env_is_wrapped(wrapper_class, indices)


def make_vec_env(
    env_id: str,
    n_envs: int = 1,
    seed: int | None = None,
    start_index: int = 0,
    monitor_dir: str | None = None,
    wrapper_class=None,
    env_kwargs: dict[str, Any] | None = None,
    vec_env_cls=None,
    vec_env_kwargs: dict[str, Any] | None = None,
    monitor_kwargs: dict[str, Any] | None = None,
    wrapper_kwargs: dict[str, Any] | None = None,
    dtype: str = "float64",
    inline_dispatch: bool = True,
) -> VecEnv:
    """See `lerax_like.sb3.make_vec_env`."""
    for name, value, instead in (
        ("wrapper_class", wrapper_class, "wrap the returned VecEnv in an SB3 VecEnvWrapper instead"),
        ("wrapper_kwargs", wrapper_kwargs, "wrap the returned VecEnv in an SB3 VecEnvWrapper instead"),
        ("vec_env_cls", vec_env_cls, "the batch is one compiled step, not a DummyVecEnv or SubprocVecEnv"),
        ("vec_env_kwargs", vec_env_kwargs, "the batch is one compiled step, not a DummyVecEnv or SubprocVecEnv"),
    ):
        if value:
            raise ValueError(f"{name} is not supported by lerax_like.sb3.make_vec_env: {instead}")
    if not isinstance(n_envs, int) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1, got {n_envs!r}")
    monitor_kwargs = dict(monitor_kwargs or {})
    unknown = set(monitor_kwargs) - {"info_keywords"}
    if unknown:
        raise ValueError(f"monitor_kwargs may only hold info_keywords (episode statistics are VecMonitor's), got {sorted(unknown)}")
    kwargs = {"render_mode": "rgb_array", **(env_kwargs or {})}
    venv = CompiledVecEnv(env_id, n_envs, dtype=dtype, inline_dispatch=inline_dispatch, **kwargs)
    if seed is not None:
        venv.action_space.seed(seed + start_index)
    venv.seed(seed)
    filename = None
    if monitor_dir is not None:
        os.makedirs(monitor_dir, exist_ok=True)
        filename = os.path.join(monitor_dir, str(start_index))
    return MonitoredVecEnv(venv, filename=filename, **monitor_kwargs)
