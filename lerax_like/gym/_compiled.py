"""The compiled steps behind the Gymnasium wrappers, and the precision scope they run in.

A scene is split once into its array leaves and its static rest. The jitted functions
take the leaves, packed into one vector of the layer's dtype (float64 by default, as
Gymnasium computes; float32 on request), as an argument (so a changed physical
parameter needs no recompile) and close over the static rest; they are cached by that
rest, so every env of the same configuration (`check_env` and `make_vec` build several)
shares one compilation. This avoids `eqx.filter_jit`, whose per-call partitioning would
dominate a step this small; and every argument and result of a jitted call costs a few
microseconds of dispatch, as much as a whole batched CartPole step, hence the packing of
the inputs into few arrays and of the results into one.
"""

import functools
import math
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..env import AbstractEnv, EnvState, step_keys
from ..spaces import Discrete


DTYPES = ("float64", "float32")
"""The dtypes the Gymnasium layer computes in: float64 (the default: Gymnasium's numbers) or float32."""


def check_dtype(dtype) -> str:
    """`dtype` as one of `DTYPES`, or a ValueError naming the parameter."""
    name = np.dtype(dtype).name if isinstance(dtype, (type, np.dtype)) else dtype
    if name not in DTYPES:
        raise ValueError(f"dtype must be one of {DTYPES}, got {dtype!r}")
    return name


def float64():
    """The scope every call into a float64 scene runs in, without a global switch."""
    return jax.enable_x64(True)


def precision(dtype: str = "float64"):
    """The scope every call into a scene of `dtype` runs in: JAX's 64-bit mode on for
    float64 and off for float32 (whatever the global setting), so that the scene's
    parameters, state and every intermediate have that precision."""
    return jax.enable_x64(check_dtype(dtype) == "float64")


def build_scene(scene_cls: type[AbstractEnv], kwargs: dict[str, Any]) -> AbstractEnv:
    """Construct the scene in float64, so that its parameters are Gymnasium's values
    (a float32 layer casts them to float32 once, in `SplitScene`)."""
    with float64():
        return scene_cls(**kwargs)


class SplitScene:
    """A scene as packed parameters and a static rest, with the compiled functions for it.

    The functions compute in `dtype`: floating-point leaves are cast to it whatever the
    dtype the scene was built in, and every call runs in `precision(dtype)`.
    `key(seed)` is the key the functions carry: `None` for a deterministic scene
    (`stochastic` False), whose starts come from NumPy here, so it needs no key work at all.
    """

    def __init__(self, scene: AbstractEnv, dtype: str = "float64"):
        self.dtype = check_dtype(dtype)
        params, static = eqx.partition(scene, eqx.is_array)
        leaves, treedef = jax.tree.flatten(params)
        with precision(self.dtype):
            real = jnp.dtype(self.dtype)
            layout = tuple(
                (leaf.shape, real if jnp.issubdtype(leaf.dtype, jnp.floating) else leaf.dtype) for leaf in leaves
            )
            flat = [jnp.ravel(leaf).astype(real) for leaf in leaves]
            self.parameters = jnp.concatenate([*flat, jnp.zeros(0, real)])
        self.scene = scene
        functions = _functions(treedef, static, layout)
        self.step, self.observe, self.vector_step, self.vector_observe, self.vector_advance, self.vector_restart = (
            functions
        )

    def precision(self):
        return precision(self.dtype)

    def key(self, seed: int) -> jax.Array | None:
        if not self.scene.stochastic:
            return None
        with self.precision():
            return jr.key(int(seed) % 2**32)


class HoldsScene:
    """The `scene` attribute the Gymnasium wrappers share: the functional env behind them,
    split and compiled (`self._split`) in the wrapper's dtype (`_dtype`), with the key its
    random parts carry."""

    _split: SplitScene
    _jax_key: jax.Array | None
    _initial_bounds: tuple[np.ndarray, np.ndarray]
    _dtype: str = "float64"

    @property
    def scene(self) -> AbstractEnv:
        """The functional env behind the wrapper. Assign a modified scene to change parameters."""
        return self._split.scene

    @scene.setter
    def scene(self, scene: AbstractEnv) -> None:
        self._split = SplitScene(scene, self._dtype)
        self._observation = None  # a vector env's last observation, stale under a new scene
        with float64():
            self._initial_bounds = tuple(np.array(bound, dtype=np.float64) for bound in scene.initial_bounds)
        # The key of a stochastic scene's random parts starts again from seed 0 (as at
        # construction; `reset(seed=...)` reseeds it); a deterministic scene needs none.
        self._jax_key = self._split.key(0)

    # Pickling (to save, checkpoint, or ship an env to a worker process): the compiled
    # functions and the renderer are dropped, and JAX arrays (the scene's leaves, the
    # key, a vector env's states) travel as NumPy arrays, so that a process without
    # float64 enabled loads them in float64. On load the scene is split again: its
    # functions come from the cache when this process compiled them already, else they
    # compile on the first call. Everything else (the NumPy generator included) is
    # copied, so a loaded copy continues exactly as the original.

    def __getstate__(self) -> dict[str, Any]:
        state = {name: value for name, value in self.__dict__.items() if name not in ("_split", "_renderer")}
        state["_scene"] = self._split.scene
        return jax.tree.map(_to_host, state)

    def __setstate__(self, state: dict[str, Any]) -> None:
        with float64():
            state = jax.tree.map(_to_device, state, is_leaf=lambda x: isinstance(x, _HostArray))
        scene = state.pop("_scene")
        self.__dict__.update(state, _renderer=None)
        self.scene = scene
        # What assigning a scene restarts (the key, a vector env's last observation) as it was.
        self.__dict__.update(state)


class _HostArray:
    """A JAX array (or key array) on the host, for pickling."""

    def __init__(self, value: jax.Array):
        self.is_key = jax.dtypes.issubdtype(value.dtype, jax.dtypes.prng_key)
        self.implementation = str(jax.random.key_impl(value)) if self.is_key else None
        self.data = np.asarray(jax.random.key_data(value) if self.is_key else value)


def _to_host(value):
    return _HostArray(value) if isinstance(value, jax.Array) else value


def _to_device(value):
    if not isinstance(value, _HostArray):
        return value
    if value.is_key:
        return jr.wrap_key_data(jnp.asarray(value.data), impl=value.implementation)
    return jnp.asarray(value.data)


def pack_step(y: np.ndarray, steps: int, action) -> np.ndarray:
    """The inputs of `SplitScene.step` as one float64 array: one host-to-device transfer."""
    return np.concatenate([np.ravel(action), [steps], y], dtype=np.float64)


def _cache(function: Callable) -> Callable:
    cached = functools.lru_cache(maxsize=64)(function)

    @functools.wraps(function)
    def wrapper(*args):
        try:
            return cached(*args)
        except TypeError:  # an unhashable static part: compile for this env alone
            return function(*args)

    return wrapper


@_cache
def _functions(treedef, static, layout):
    def scene_of(parameters) -> AbstractEnv:
        leaves, start = [], 0
        for shape, dtype in layout:
            size = math.prod(shape)
            leaves.append(parameters[start : start + size].reshape(shape).astype(dtype))
            start += size
        return eqx.combine(jax.tree.unflatten(treedef, leaves), static)

    def next_key(key, num_envs=None):
        """The carried key and this call's key (one per env, given `num_envs`); none for a
        deterministic scene, which carries no key (see `SplitScene.key`)."""
        if key is None:
            return None, None
        key, call_key = jr.split(key)
        return key, (call_key if num_envs is None else jr.split(call_key, num_envs))

    def advance(scene, y, steps, action, key, observation_before=None):
        # The functional env's step semantics (`AbstractEnv.advance`), with the float32
        # observation Gymnasium returns checked for finiteness after the cast: a finite
        # float64 state can still overflow float32. The vector steps pass the observation
        # of `y` they returned last, so that `advance` does not compute it again.
        state, observation, reward, terminated, info = scene.advance(
            EnvState(y=y, steps=steps), action, key=key, observation_dtype=jnp.float32,
            observation_before=observation_before,
        )
        return state.y, observation, reward, terminated, info

    def observe_one(scene, y, steps, key):
        key = step_keys(key, scene.stochastic).observation
        return scene.observation(EnvState(y=y, steps=steps), key=key).astype(jnp.float32)

    def vector_actions(scene, action):
        if isinstance(scene.action_space, Discrete):
            return action.astype(int)
        return action.astype(parameters_dtype(scene))

    def parameters_dtype(scene):
        return jnp.asarray(scene.dt).dtype

    def vector_advance_all(scene, y, steps, action, key, max_episode_steps, observation):
        """`advance` of every env (`observation`: the observation of `y`), and the time limit."""
        key, keys = next_key(key, num_envs=y.shape[0])
        action = vector_actions(scene, action)
        next_y, observation, reward, terminated, info = jax.vmap(advance, in_axes=(None, 0, 0, 0, 0, 0))(
            scene, y, steps, action, keys, observation
        )
        steps = steps + 1
        truncated = steps >= max_episode_steps
        return key, next_y, steps, observation, reward, terminated, truncated, info

    def outcome_rows(reward, terminated, truncated, info):
        # One array for the host besides the observation: the reward, the flags and the
        # solver info, one row each (rows of it are contiguous arrays on the host).
        flags = (reward, terminated, truncated, info["solver_ok"], info["solver_steps"])
        return jnp.stack([jnp.astype(x, reward.dtype) for x in flags])

    @jax.jit
    def step(parameters, inputs, key):
        """One step from `inputs = [action..., steps, y...]`, packed by `pack_step`."""
        scene = scene_of(parameters)
        space = scene.action_space
        size = math.prod(space.shape)
        action = inputs[:size].reshape(space.shape)
        if isinstance(space, Discrete):
            action = action.astype(int)
        steps, y = inputs[size].astype(int), inputs[size + 1 :]
        key, step_key = next_key(key)
        next_y, observation, reward, terminated, info = advance(scene, y, steps, action, step_key)
        # One array for the host: the next state, the (float32) observation, the reward,
        # the flag and the solver info.
        flags = (reward, terminated, info["solver_ok"], info["solver_steps"])
        flags = jnp.stack([jnp.astype(x, next_y.dtype) for x in flags])
        return jnp.concatenate([next_y, observation.astype(next_y.dtype), flags]), key

    @jax.jit
    def observe(parameters, y, steps, key):
        scene = scene_of(parameters)
        key, observation_key = next_key(key)
        return observe_one(scene, y, steps, observation_key), key

    @jax.jit
    def vector_advance(parameters, y, steps, action, key, max_episode_steps, observation):
        """All envs step (`advance`), none restarts: `(y, steps, observation, outcome, key)`.

        `observation` is the observation of `y` (the last one returned), which a failed
        step returns again.
        The outcome rows are the reward, terminated, truncated (`steps >= max_episode_steps`),
        `solver_ok` and `solver_steps`.
        """
        scene = scene_of(parameters)
        key, next_y, steps, observation, reward, terminated, truncated, info = vector_advance_all(
            scene, y, steps, action, key, max_episode_steps, observation
        )
        return next_y, steps, observation, outcome_rows(reward, terminated, truncated, info), key

    @jax.jit
    def vector_step(parameters, y, steps, action, key, reset_mask, reset_y, max_episode_steps, observation):
        """All envs step; then those whose episode ended at the previous step restart.

        Gymnasium's next-step autoreset: a restarted env (`reset_mask`) continues from
        `reset_y` and returns its fresh observation, reward 0, terminated and truncated
        False. One compilation serves every time limit and every pattern of restarts;
        a step where no env restarts is `vector_advance`, which skips all of this.
        """
        scene = scene_of(parameters)
        key, next_y, steps, observation, reward, terminated, truncated, info = vector_advance_all(
            scene, y, steps, action, key, max_episode_steps, observation
        )
        # Restarted envs continue from `reset_y` with their fresh observation.
        next_y = jnp.where(reset_mask[:, None], reset_y, next_y)
        steps = jnp.where(reset_mask, 0, steps)
        key, keys = next_key(key, num_envs=y.shape[0])
        fresh = jax.vmap(observe_one, in_axes=(None, 0, 0, 0))(scene, reset_y, steps, keys)
        observation = jnp.where(reset_mask[:, None], fresh, observation)
        reward = jnp.where(reset_mask, 0, reward)
        terminated = terminated & ~reset_mask
        truncated = truncated & ~reset_mask
        info = {
            "solver_ok": info["solver_ok"] | reset_mask,
            "solver_steps": jnp.where(reset_mask, 0, info["solver_steps"]),
        }
        return next_y, steps, observation, outcome_rows(reward, terminated, truncated, info), key

    @jax.jit
    def vector_restart(parameters, y, steps, key, reset_mask, reset_y, observation):
        """Restart the envs of `reset_mask` from `reset_y`: `(y, steps, observation, key)`,
        the observation being the fresh one for those envs and `observation` for the others.

        What SB3's same-step autoreset needs after `vector_advance`.
        """
        scene = scene_of(parameters)
        y = jnp.where(reset_mask[:, None], reset_y, y)
        steps = jnp.where(reset_mask, 0, steps)
        key, keys = next_key(key, num_envs=y.shape[0])
        fresh = jax.vmap(observe_one, in_axes=(None, 0, 0, 0))(scene, reset_y, steps, keys)
        return y, steps, jnp.where(reset_mask[:, None], fresh, observation), key

    @jax.jit
    def vector_observe(parameters, y, steps, key):
        scene = scene_of(parameters)
        key, observation_keys = next_key(key, num_envs=y.shape[0])
        observation = jax.vmap(observe_one, in_axes=(None, 0, 0, 0))(scene, y, steps, observation_keys)
        return observation, key

    return step, observe, vector_step, vector_observe, vector_advance, vector_restart


__all__ = ["DTYPES", "HoldsScene", "SplitScene", "build_scene", "check_dtype", "float64", "pack_step", "precision"]
