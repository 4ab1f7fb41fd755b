"""`GymnasiumVectorEnv`: many copies of a scene stepped by one compiled, batched step."""

from typing import Any, cast

import gymnasium
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _render
from ._attributes import GymnasiumAttributes
from ._inputs import check_actions
from ._batch import Batch, Outcome
from ._compiled import build_scene, check_dtype, float64
from ._spaces import to_gymnasium_space
from ._specs import GymSpec
from .._types import IntScalar


class GymnasiumVectorEnv(GymnasiumAttributes, VectorEnv):
    """`num_envs` copies of a scene (what `gymnasium.make_vec("lerax_like/<id>", N,
    vectorization_mode="vector_entry_point")` builds).

    One call of `step` is one compiled, batched step of all envs (`batch`, a `Batch`),
    integrated in `dtype`. `autoreset_mode` is one of Gymnasium's (`metadata["autoreset_mode"]`),
    with the semantics Gymnasium documents for them and its `SyncVectorEnv` has: `NEXT_STEP`
    (the default, as Gymnasium's vector CartPole), `SAME_STEP` (`info["final_obs"]` and
    `info["final_info"]`), `DISABLED` (`reset(options={"reset_mask": mask})`; stepping an
    env that ended without resetting it is refused).

    Initial states are drawn on the host from `self.np_random` with the calls of
    Gymnasium's vector CartPole (`uniform(size=(4, num_envs))` at reset, one draw of
    shape `(4, number of restarted envs)` at a step that restarts some), and only at such
    steps, with the options of the last reset; so for CartPole the same seed and actions
    give Gymnasium's numbers.

    `dtype` is the precision of the step: `"float64"` (the default) computes as Gymnasium
    does, `"float32"` as JAX users run on accelerators (the parameters are cast once; the
    starts are drawn as above, then rounded). Observations are float32 either way.

    `state` is readable and writable. The info holds the per-env `solver_ok`,
    `solver_steps` and `action_ok`, with Gymnasium's `_name` masks. Rewards are of `dtype`.
    Gymnasium's attributes of the id's env (`masspole`, `tau`, ...) read and write the scene
    all envs share (`GymnasiumAttributes`).
    Actions are checked on the host: one that cannot be applied (out of range, not an
    integer, not finite) is refused with a `ValueError` naming it and the space.

    The steps are compiled when the env is made (`warm_up=False`: at their first call).
    On a CPU, see docs/performance.md for JAX's dispatch, which costs as much as a small step.
    """

    # What `to_gymnasium_space` builds (Gymnasium declares any `Space`).
    single_action_space: gymnasium.spaces.Discrete | gymnasium.spaces.Box
    single_observation_space: gymnasium.spaces.Discrete | gymnasium.spaces.Box

    metadata = {
        "render_modes": ["human", "rgb_array", "rgb_array_list"],
        "render_fps": 50,
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        spec: GymSpec,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        dtype: str = "float64",
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        *,
        warm_up: bool = True,
        **scene_kwargs: Any,
    ):
        dtype = check_dtype(dtype)
        if max_episode_steps is not None and (not isinstance(max_episode_steps, int) or max_episode_steps < 1):
            raise ValueError(f"max_episode_steps must be None or an integer >= 1, got {max_episode_steps!r}")
        try:
            self.autoreset_mode = AutoresetMode(autoreset_mode)
        except ValueError as error:
            modes = [mode.value for mode in AutoresetMode]
            raise ValueError(f"autoreset_mode must be one of {modes}, got {autoreset_mode!r}") from error
        self._gym_spec = spec
        # The time limit is the scene's (`AbstractEnv.truncate`).
        scene = build_scene(spec.scene, {**scene_kwargs, "max_episode_steps": max_episode_steps})
        self.batch = Batch(scene, num_envs, dtype)
        self.num_envs = num_envs
        with float64():
            self.single_action_space = to_gymnasium_space(scene.action_space)
            self.single_observation_space = to_gymnasium_space(scene.observation_space)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.metadata = {
            **self.metadata, "render_fps": _render.render_fps(spec), "autoreset_mode": self.autoreset_mode,
        }
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer = None
        self._window = None  # the human mode's
        self._options: dict[str, Any] | None = None
        self._ended = np.zeros(num_envs, dtype=np.bool_)  # the envs whose episode ended at the last step
        self.last_action: np.ndarray | None = None  # what the renderer draws (Pendulum's torque)
        self._info_mask = np.ones(num_envs, dtype=np.bool_)
        if warm_up:  # compile the steps now, not in the first step of training
            self.warm_up_moves(
                fused=self.autoreset_mode == AutoresetMode.NEXT_STEP,
                restart=self.autoreset_mode != AutoresetMode.NEXT_STEP,
            )

    def warm_up_moves(self, **moves: bool) -> None:
        """Compile the batch's moves named True (`Batch.warm_up`) on throwaway states."""
        if isinstance(self.single_action_space, gymnasium.spaces.Discrete):
            zero = np.full(self.num_envs, self.single_action_space.start, dtype=np.int64)
        else:
            zero = np.zeros((self.num_envs, *self.single_action_space.shape), dtype=self.dtype)
        self.batch.warm_up(self.starts(np.random.default_rng(0), None, self.num_envs), zero, **moves)

    @property
    def dtype(self) -> str:
        """The precision of the step: `"float64"` or `"float32"`."""
        return self.batch.dtype

    @property
    def max_episode_steps(self) -> IntScalar | None:
        """The time limit: the scene's `max_episode_steps`."""
        return self.batch.scene.max_episode_steps

    @property
    def scene(self):
        """The functional env behind the vector env. Assign a modified scene to change parameters."""
        return self.batch.scene

    @scene.setter
    def scene(self, scene) -> None:
        self.batch.scene = scene

    @property
    def state(self) -> np.ndarray | None:
        """The states, of `dtype`, shape `(n, num_envs)` (Gymnasium's vector CartPole layout)."""
        state = self.batch.state
        return None if state is None else state.T

    @state.setter
    def state(self, value) -> None:
        value = np.asarray(value)
        expected = (self.batch.initial_bounds[0].size, self.num_envs)
        if value.shape != expected:
            raise ValueError(f"state must have shape {expected} (state size, num_envs), got shape {value.shape}")
        self.batch.state = value.T

    def starts(self, np_random: np.random.Generator, options: dict[str, Any] | None, count: int) -> np.ndarray:
        """`count` starts drawn from `np_random` as Gymnasium draws them, shape `(count, n)`, of `dtype`."""
        starts = self._gym_spec.initial_state(self.batch.initial_bounds, np_random, options, count).T
        return starts.astype(self.dtype, copy=False)

    def starts_each(self, generators: list[np.random.Generator], options: list[dict[str, Any] | None]) -> np.ndarray:
        """One start from each generator with its options (each env's own, as Gymnasium's
        single env draws it), shape `(len(generators), n)`, of `dtype`.

        One call for all of them (SB3's envs have a generator each, and some restart at most
        steps): what is the same for every env is done once.
        """
        starts = self._gym_spec.initial_state_each(self.batch.initial_bounds, generators, options).T
        return starts.astype(self.dtype, copy=False)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if seed is not None:
            self.batch.seed(seed)
        if options is not None and "reset_mask" in options:
            return self._reset_masked(dict(options)), {}
        self._options = options
        observation = self.batch.reset(self.starts(self.np_random, options, self.num_envs))
        self._ended = np.zeros(self.num_envs, dtype=np.bool_)
        self.last_action = None
        self._shown()
        return observation, {}

    def _reset_masked(self, options: dict[str, Any]) -> np.ndarray:
        # Gymnasium's `SyncVectorEnv.reset`: the envs of the mask restart, the others stay.
        mask = options.pop("reset_mask")
        if not isinstance(mask, np.ndarray):
            raise TypeError(f"`options['reset_mask']` must be a numpy array, got {type(mask)}")
        if mask.shape != (self.num_envs,):
            raise ValueError(f"`options['reset_mask']` must have shape `({self.num_envs},)`, got {mask.shape}")
        if mask.dtype != np.bool_:
            raise TypeError(f"`options['reset_mask']` must have `dtype=np.bool_`, got {mask.dtype}")
        if not mask.any():
            raise ValueError(f"`options['reset_mask']` must contain at least one True value, got reset_mask={mask}")
        if self.batch.state is None:
            raise RuntimeError("call reset without a reset_mask first: no env has started")
        self._options = options or None
        starts = self.starts(self.np_random, self._options, int(np.count_nonzero(mask)))
        self._ended = self._ended & ~mask
        observation = self.batch.restart(mask, starts)
        self._shown()
        return observation

    def step(self, actions):
        actions = check_actions(self.single_action_space, actions, self.num_envs, self.batch.dtype)
        mode = self.autoreset_mode
        # np.count_nonzero: one C call (`ndarray.any` goes through a Python wrapper), the
        # number of restarts, which the draw needs.
        ended = int(np.count_nonzero(self._ended))
        if ended and mode is AutoresetMode.DISABLED:
            raise RuntimeError(
                f"envs {np.flatnonzero(self._ended).tolist()} ended at the last step: with autoreset_mode "
                "DISABLED, restart them with reset(options={'reset_mask': mask}) before stepping"
            )
        restarts = self._ended if ended and mode is AutoresetMode.NEXT_STEP else None
        if restarts is not None:
            # Gymnasium's vector CartPole draws only when some env restarts, for those envs.
            starts = self.starts(self.np_random, self._options, ended)
            outcome = self.batch.advance_or_restart(actions, restarts, starts)
            # An env that restarted has only its reset's info, which is empty.
            mask = None if ended == self.num_envs else ~restarts
        else:
            outcome = self.batch.advance(actions)
            mask = self._info_mask
        self.last_action = actions
        self._ended = outcome.terminated | outcome.truncated
        observation, info = outcome.observation, {}
        if mode is AutoresetMode.SAME_STEP and np.count_nonzero(self._ended):
            ended = self._ended
            final_obs = np.full(self.num_envs, None, dtype=object)
            for index in np.flatnonzero(ended):
                final_obs[index] = observation[index].copy()
            info = {
                "final_obs": final_obs, "_final_obs": ended.copy(),
                "final_info": self._info(outcome, ended), "_final_info": ended.copy(),
            }
            # An env that restarts has only its reset's info, which is empty.
            mask = None if ended.all() else ~ended
            starts = self.starts(self.np_random, self._options, int(np.count_nonzero(ended)))
            observation = self.batch.restart(ended, starts)
        self._shown()
        return observation, outcome.reward, outcome.terminated, outcome.truncated, {**self._info(outcome, mask), **info}

    def _info(self, outcome: Outcome, mask: np.ndarray | None) -> dict[str, np.ndarray]:
        """The step's info for the envs of `mask` (None: no env), as Gymnasium's `_add_info`
        builds it: a key only when some env has it."""
        if mask is None:
            return {}
        mask = mask.copy()  # one copy for the three keys, which have the same envs
        return {
            "solver_ok": outcome.solver_ok, "_solver_ok": mask,
            "solver_steps": outcome.solver_steps, "_solver_steps": mask,
            "action_ok": outcome.action_ok, "_action_ok": mask,
        }

    def __getstate__(self) -> dict[str, Any]:
        return {name: value for name, value in self.__dict__.items() if name not in ("_renderer", "_window")}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state, _renderer=None, _window=None)

    # -- rendering: each mode as Gymnasium's `SyncVectorEnv` of envs made with it ----------

    def frame(self, index: int) -> np.ndarray:
        """Env `index`'s picture (an RGB array), drawn from its state and scene (by Gymnasium's
        renderer for an id standing for Gymnasium's env)."""
        states = self.state
        if states is None:
            raise ValueError("the state is None: call reset before render")
        if self._renderer is None:
            self._renderer = _render.make_renderer(self._gym_spec, "rgb_array")
        action = None if self.last_action is None else self.last_action[index]
        # An rgb_array renderer: its draw returns the frame.
        return cast(np.ndarray, self._renderer.draw(self.batch.scene_at(index), states[:, index], action))

    def _frames(self) -> list[np.ndarray]:
        return [self.frame(index) for index in range(self.num_envs)]

    def show(self) -> None:
        """Show every env, tiled in one pygame window (`human`; the window opens at the first call)."""
        if self._window is None:
            self._window = _render.HumanWindow(self.metadata["render_fps"])
        self._window.show(_render.tile(self._frames()))

    def _shown(self) -> None:
        """`human`: every reset and step shows every env, tiled in one window, as each of
        `SyncVectorEnv`'s human envs draws itself."""
        if self.render_mode == "human":
            self.show()

    def render(self):
        """One frame per env (an RGB array each) in `rgb_array` and `rgb_array_list`; in `human`,
        one None per env, as every reset and step shows the envs.

        `rgb_array_list` returns the envs' current frames, as Gymnasium's own vector CartPole
        does (`gymnasium.make_vec("CartPole-v1", n, render_mode="rgb_array_list")`), since
        Gymnasium's vector wrappers (`HumanRendering`, `RecordVideo`) take one array per env
        from `render` in every image mode. Each env's frames since its reset, as
        `RenderCollection` keeps them, come from `vectorization_mode="sync"`, whose envs are
        `gymnasium.make`'s single envs (and which `HumanRendering` refuses for that reason).
        """
        if self.render_mode is None:
            gymnasium.logger.warn(
                "You are calling render method without specifying any render mode. "
                "You can specify the render_mode at initialization, "
                f'e.g. gym.make_vec("{self._gym_spec.id}", render_mode="rgb_array")'
            )
            return None
        if self.render_mode == "human":
            return (None,) * self.num_envs
        return self._frames()

    def close_extras(self, **kwargs: Any) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._window is not None:
            self._window.close()
            self._window = None
