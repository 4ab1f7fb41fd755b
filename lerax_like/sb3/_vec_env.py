"""`CompiledVecEnv`: an SB3 `VecEnv` whose step is the vector env's compiled, batched step."""

import os
from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium.utils import seeding
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

from ..gym import SPECS, GymnasiumVectorEnv
from ..gym._inputs import check_actions


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

    One step is `Batch.advance` (one compiled call of all envs) and, only when some
    episode ended, `Batch.restart` of those envs ("advance, then restart"); their starts
    are drawn on the host for them alone. Actions that cannot be applied are refused
    with a `ValueError` naming them. Attributes (`get_attr`, `set_attr`, `env_method`) are those of
    the `GymnasiumVectorEnv` behind it (`scene`, `state`, `render_mode`), shared by all
    envs: `set_attr` applies to all of them or refuses.
    """

    def __init__(
        self,
        env_id: str,
        num_envs: int = 1,
        *,
        max_episode_steps: int | None = None,
        render_mode: str | None = None,
        dtype: str = "float64",
        **scene_kwargs: Any,
    ):
        if env_id not in SPECS:
            raise ValueError(f"env_id must be one of {tuple(SPECS)}, got {env_id!r}")
        spec = SPECS[env_id]
        if max_episode_steps is None:
            max_episode_steps = spec.max_episode_steps
        # The vector env holds the batch, the spaces, the renderer and the attributes; its
        # own autoreset is not used: this env restarts in its step, through the batch.
        self._vector = GymnasiumVectorEnv(
            spec, num_envs=num_envs, max_episode_steps=max_episode_steps, render_mode=render_mode, dtype=dtype,
            autoreset_mode=gymnasium.vector.AutoresetMode.SAME_STEP, **scene_kwargs,
        )
        self._batch = self._vector.batch
        self.spec = gymnasium.spec(env_id)
        self.max_episode_steps = max_episode_steps
        self._generators: list[np.random.Generator | None] = [None] * num_envs
        self._actions: np.ndarray | None = None
        super().__init__(num_envs, self._vector.single_observation_space, self._vector.single_action_space)

    # -- SB3's VecEnv ------------------------------------------------------------------

    def reset(self):
        for index, seed in enumerate(self._seeds):
            if seed is not None or self._generators[index] is None:
                self._generators[index], _ = seeding.np_random(seed)
        if self._seeds[0] is not None:
            self._batch.seed(self._seeds[0])
        observation = self._batch.reset(self._starts(range(self.num_envs)))
        self.reset_infos = [{} for _ in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return observation

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        actions = check_actions(self.action_space, self._actions, self.num_envs, self._batch.dtype)
        outcome = self._batch.advance(actions)
        observation = outcome.observation
        reward = outcome.reward.astype(np.float32)
        done = outcome.terminated | outcome.truncated
        time_limit = (outcome.truncated & ~outcome.terminated).tolist()
        infos = [
            {"solver_ok": ok, "solver_steps": steps, "action_ok": action_ok, "TimeLimit.truncated": limit}
            for ok, steps, action_ok, limit in zip(
                outcome.solver_ok.tolist(), outcome.solver_steps.tolist(), outcome.action_ok.tolist(), time_limit
            )
        ]
        ended = np.flatnonzero(done)
        if ended.size:
            for index in ended:
                infos[index]["terminal_observation"] = observation[index].copy()
            fresh = self._batch.restart(done, self._starts(ended))
            observation[ended] = fresh[ended]
        self._vector.last_action = actions
        return observation, reward, done, infos

    def _starts(self, indices) -> np.ndarray:
        """Starts of the envs `indices`, each drawn from its own generator as Gymnasium's env draws it."""
        starts = [self._vector.starts(self._generators[index], self._options[index] or None, 1) for index in indices]
        return np.concatenate(starts)

    def close(self) -> None:
        self._vector.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        if self.render_mode != "rgb_array":
            return [None] * self.num_envs
        return self._vector.render()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        value = getattr(self._vector, attr_name)
        return [value] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        if len(self._indices(indices)) != self.num_envs:
            raise ValueError(
                f"set_attr({attr_name!r}) must apply to all {self.num_envs} envs (indices=None): "
                "they share one compiled step"
            )
        setattr(self._vector, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        result = getattr(self._vector, method_name)(*method_args, **method_kwargs)
        return [result] * len(self._indices(indices))

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)

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


_UNSUPPORTED = {
    "wrapper_class": "wrap the returned VecEnv in an SB3 VecEnvWrapper instead",
    "wrapper_kwargs": "wrap the returned VecEnv in an SB3 VecEnvWrapper instead",
    "vec_env_cls": "the batch is one compiled step, not a DummyVecEnv or SubprocVecEnv",
    "vec_env_kwargs": "the batch is one compiled step, not a DummyVecEnv or SubprocVecEnv",
}


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
) -> VecEnv:
    """See `lerax_like.sb3.make_vec_env`."""
    given = {"wrapper_class": wrapper_class, "wrapper_kwargs": wrapper_kwargs, "vec_env_cls": vec_env_cls,
             "vec_env_kwargs": vec_env_kwargs}
    for name, value in given.items():
        if value:
            raise ValueError(f"{name} is not supported by lerax_like.sb3.make_vec_env: {_UNSUPPORTED[name]}")
    if not isinstance(n_envs, int) or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1, got {n_envs!r}")
    monitor_kwargs = dict(monitor_kwargs or {})
    unknown = set(monitor_kwargs) - {"info_keywords"}
    if unknown:
        raise ValueError(f"monitor_kwargs may only hold info_keywords (episode statistics are VecMonitor's), got {sorted(unknown)}")
    kwargs = {"render_mode": "rgb_array", **(env_kwargs or {})}
    venv = CompiledVecEnv(env_id, n_envs, dtype=dtype, **kwargs)
    if seed is not None:
        venv.action_space.seed(seed + start_index)
    venv.seed(seed)
    filename = None
    if monitor_dir is not None:
        os.makedirs(monitor_dir, exist_ok=True)
        filename = os.path.join(monitor_dir, str(start_index))
    return VecMonitor(venv, filename=filename, **monitor_kwargs)


__all__ = ["CompiledVecEnv", "make_vec_env"]
