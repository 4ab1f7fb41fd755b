"""`Batch`: the one owner of a batch of envs' states, step counts, key and last observations.

Gymnasium's vector env and SB3's `VecEnv` are front ends on it, each with its own order
of the two moves a batch makes: `advance` (every env steps, `AbstractEnv.advance` and
`truncate`, in one compiled call) and `restart` (the envs of a mask start again from
given starts). Gymnasium's next-step autoreset is "restart, then advance" (fused into one
call, `advance_or_restart`), its same-step autoreset and SB3's are "advance, then
restart". The starts come from the front end, which draws them with NumPy in
Gymnasium's order of calls: the batch only places them.
"""

from typing import Any, NamedTuple, final

import jax
import jax.numpy as jnp
import numpy as np

from ..env import AbstractEnv
from ._compiled import Compiled, SplitScene, VecStep, float64, to_device, to_host, to_numpy, unpack_vec_step
from ._inputs import check_state


class Outcome(NamedTuple):
    """A batch step's results on the host, one entry per env."""

    observation: np.ndarray
    """float32, the observation after the step (or the restart)."""
    reward: np.ndarray
    """Of the batch's dtype."""
    terminated: np.ndarray
    truncated: np.ndarray
    """The time limit, `AbstractEnv.truncate`."""
    solver_ok: np.ndarray
    solver_steps: np.ndarray
    action_ok: np.ndarray
    """True for every env: the front ends refuse an inadmissible action (`check_actions`)
    before it reaches the batch, so the compiled step does not return the flag."""


@jax.jit
def _jitted_copy(array):
    # A jitted copy: jit's C++ path takes a NumPy array in a few microseconds, where
    # `jax.device_put`'s Python layers take 30 (hot) to over 100 (in a training loop).
    return array * 1


@final
class Batch:
    """`num_envs` copies of `scene`, stepped together by compiled, batched calls in `dtype`.

    A failed step returns the last `observation` again. `scene` may be replaced (new
    parameters: the same compiled program when only array leaves change); the states stay.
    The time limit is the scene's `max_episode_steps`.

    `set_scenes` gives some envs scenes of their own (other parameters, same
    configuration): the compiled calls then take one parameter row per env; assigning
    `scene` makes every env share it again.
    """

    def __init__(self, scene: AbstractEnv, num_envs: int, dtype: str = "float64"):
        if not isinstance(num_envs, int) or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.num_envs = num_envs
        self._split = SplitScene(scene, dtype)
        self._key = self._split.key(0)
        with float64():
            self.initial_bounds = tuple(np.array(bound, dtype=np.float64) for bound in scene.initial_bounds)
        self._y: jax.Array | None = None
        self._steps: jax.Array | None = None
        self._observation: jax.Array | None = None  # the last one returned; None when stale
        self._scenes: list[AbstractEnv] | None = None  # per-env scenes, None while all share `scene`
        self._rows: jax.Array | None = None  # their packed parameters, one row per env
        # Restarts place their starts in this buffer: the rows of envs that do not restart are unused.
        self._starts = np.zeros((num_envs, self.initial_bounds[0].size), dtype=self.dtype)

    # -- what the batch holds ------------------------------------------------------------

    @property
    def dtype(self) -> str:
        return self._split.dtype

    @property
    def scene(self) -> AbstractEnv:
        return self._split.scene

    @scene.setter
    def scene(self, scene: AbstractEnv) -> None:
        self._split = SplitScene(scene, self.dtype)
        self._key = self._split.carried_key(self._key)
        self._scenes = self._rows = None
        self._observation = None  # of the old scene: the next step observes again

    def scene_at(self, index: int) -> AbstractEnv:
        """The scene env `index` steps with."""
        return self.scene if self._scenes is None else self._scenes[index]

    def set_scenes(self, indices: list[int], scenes: list[AbstractEnv]) -> None:
        """Env `indices[k]` steps with `scenes[k]` from its next step on; the other envs keep theirs.

        The scenes may differ from the batch's in their array parameters only (a solver, a
        shape or a Python value would need another compiled program): anything else is
        refused with a ValueError.
        """
        rows = []
        for index, scene in zip(indices, scenes, strict=True):
            split = SplitScene(scene, self.dtype)
            if split.compiled is not self._split.compiled:
                raise ValueError(
                    f"env {index}'s scene differs from the batch's in more than its array parameters "
                    "(solver, static fields): assign it to `scene`, for every env, instead"
                )
            rows.append(split.parameters)
        if self._scenes is None or self._rows is None:  # both None while all envs share `scene`
            self._scenes = [self.scene] * self.num_envs
            with self._split.precision():
                self._rows = jnp.tile(self._split.parameters, (self.num_envs, 1))
        for index, scene in zip(indices, scenes, strict=True):
            self._scenes[index] = scene
        with self._split.precision():
            self._rows = self._rows.at[jnp.asarray(indices, dtype=int)].set(jnp.stack(rows))
        self._observation = None

    @property
    def parameters(self) -> jax.Array:
        """The compiled functions' first argument: the scene's array leaves packed into one
        vector of `dtype`, or one row per env after `set_scenes`."""
        return self._split.parameters if self._rows is None else self._rows

    @property
    def key(self) -> jax.Array | None:
        """The key a stochastic scene's random parts carry (None for a deterministic scene)."""
        return self._key

    @property
    def compiled(self) -> Compiled:
        """The compiled functions of the current scene (shared by every batch of its configuration)."""
        return self._split.compiled

    def seed(self, seed: int) -> None:
        """Restart the key of a stochastic scene's random parts from `seed` (nothing for a deterministic one)."""
        self._key = self._split.key(seed)

    @property
    def state(self) -> np.ndarray | None:
        """The states, shape `(num_envs, n)` (None before the first reset): a copy."""
        return None if self._y is None else to_numpy(self._y)

    @state.setter
    def state(self, value) -> None:
        value = check_state(value, self._starts.shape, self.dtype, "num_envs, state size")
        with self._split.precision():
            self._y = jnp.asarray(value)
            if self._steps is None:
                self._steps = jnp.zeros(self.num_envs, dtype=int)
        self._observation = None  # of the old state: the next step observes the new one

    @property
    def steps(self) -> np.ndarray | None:
        """The env steps taken in each env's episode."""
        return None if self._steps is None else to_numpy(self._steps)

    @property
    def observation(self) -> np.ndarray:
        """The envs' current observations (float32, a copy)."""
        return to_numpy(self._current_observation())

    # -- the moves -----------------------------------------------------------------------

    def reset(self, starts: np.ndarray) -> np.ndarray:
        """Start every env from `starts` (shape `(num_envs, n)`); returns the observations."""
        split = self._split
        with split.precision():
            self._y = jnp.asarray(starts, dtype=self.dtype)
            self._steps = jnp.zeros(self.num_envs, dtype=int)
            self._observation, self._key = split.compiled.batch_observe(
                self.parameters, self._y, self._steps, self._key
            )
        return to_numpy(self._current_observation())

    def advance(self, actions: np.ndarray) -> Outcome:
        """Every env steps with its action (checked by the front end: `check_actions`)."""
        split = self._split
        observation = self._current_observation()
        with split.precision():
            outputs = split.compiled.batch_advance(
                self.parameters, self._y, self._steps, actions, self._key, observation
            )
        return self._take(outputs)

    def advance_or_restart(self, actions: np.ndarray, mask: np.ndarray, starts: np.ndarray) -> Outcome:
        """The envs of `mask` restart from `starts` (one row each, in order), the others step:
        a restarted env returns its fresh observation, reward 0, no end, `solver_ok`."""
        split = self._split
        observation = self._current_observation()
        self._starts[mask] = starts
        with split.precision():
            outputs = split.compiled.batch_advance_or_restart(
                self.parameters, self._y, self._steps, actions, self._key, observation, mask, self._starts
            )
        return self._take(outputs)

    def restart(self, mask: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The envs of `mask` restart from `starts` (one row each, in order); returns every
        env's observation (the fresh one for those envs)."""
        split = self._split
        observation = self._current_observation()
        self._starts[mask] = starts
        with split.precision():
            self._y, self._steps, self._observation, self._key = split.compiled.batch_restart(
                self.parameters, self._y, self._steps, self._key, observation, mask, self._starts
            )
        return to_numpy(self._current_observation())

    def advance_then_restart(self, actions: np.ndarray, starts: jax.Array | None) -> VecStep:
        """Every env steps with its action; given `starts` (one row per env, drawn before
        the step, on the device: `device_copy`), the envs whose episode ended restart from
        their row in the same call (SB3's same-step autoreset), else they are left ended
        for `restart`.

        The actions may be unchecked: if one cannot be applied (`VecStep.admissible`
        False), nothing changes and the front end refuses the step.
        """
        split = self._split
        observation = self._current_observation()
        with split.precision():
            y, steps, observation, summary, key = split.compiled.batch_advance_then_restart(
                self.parameters, self._y, self._steps, actions, self._key, observation, starts
            )
        step = unpack_vec_step(summary, observation.shape)
        if step.admissible:
            self._y, self._steps, self._observation, self._key = y, steps, observation, key
        return step

    def device_copy(self, states: np.ndarray) -> jax.Array:
        """A copy of `states` (one row per env) on the device, in the batch's dtype: a
        start that several steps pass costs no transfer at each."""
        # A NumPy copy first: the device may share a CPU array's memory, and the caller's
        # `states` may change.
        with self._split.precision():
            return _jitted_copy(np.array(states, dtype=self.dtype))

    def warm_up(
        self, starts: np.ndarray, actions: np.ndarray, *, advance: bool = True, fused: bool = False,
        restart: bool = False, advance_then_restart: bool = False,
    ) -> None:
        """Compile what a front end will call (the moves of those names) on throwaway
        states, not in the first step of training."""
        split = self._split
        with split.precision():
            y = jnp.asarray(starts, dtype=self.dtype)
            steps = jnp.zeros(self.num_envs, dtype=int)
            no_restart = np.zeros(self.num_envs, dtype=np.bool_)
            observation, _ = split.compiled.batch_observe(self.parameters, y, steps, self._key)
            arguments = (self.parameters, y, steps, actions, self._key, observation)
            if advance:
                jax.block_until_ready(split.compiled.batch_advance(*arguments))
            if advance_then_restart:
                jax.block_until_ready(split.compiled.batch_advance_then_restart(*arguments, self.device_copy(starts)))
            if fused:
                jax.block_until_ready(split.compiled.batch_advance_or_restart(*arguments, no_restart, starts))
            if restart:
                jax.block_until_ready(
                    split.compiled.batch_restart(self.parameters, y, steps, self._key, observation, no_restart, starts)
                )

    # -- internals -----------------------------------------------------------------------

    def _current_observation(self) -> jax.Array:
        if self._y is None:
            raise RuntimeError("call reset before step")
        observation = self._observation
        if observation is None:  # the state or the scene was assigned
            split = self._split
            with split.precision():
                observation, self._key = split.compiled.batch_observe(self.parameters, self._y, self._steps, self._key)
            self._observation = observation
        return observation

    def _take(self, outputs) -> Outcome:
        self._y, self._steps, self._observation, rows, self._key = outputs
        # A writable copy of each (`to_numpy`), not jax.device_get: the latter costs far
        # more for arrays this small. Every result is a new array.
        rows = to_numpy(rows)
        flags = rows[1:4] != 0  # one NumPy call for the three flags: host calls dominate a small step
        return Outcome(
            to_numpy(self._current_observation()), rows[0], flags[0], flags[1], flags[2], rows[4].astype(np.int64),
            np.ones(self.num_envs, dtype=np.bool_),
        )

    # Pickling (to save, checkpoint, or ship to a worker process): the compiled functions
    # are dropped and JAX arrays travel as NumPy arrays; on load the scene is split again
    # (its functions come from the cache when this process compiled them already).

    def __getstate__(self) -> dict[str, Any]:
        state = {name: value for name, value in self.__dict__.items() if name != "_split"}
        return to_host({**state, "_scene": self.scene, "_dtype": self.dtype})

    def __setstate__(self, state: dict[str, Any]) -> None:
        state = to_device(state)
        self._split = SplitScene(state.pop("_scene"), state.pop("_dtype"))
        self.__dict__.update(state)
