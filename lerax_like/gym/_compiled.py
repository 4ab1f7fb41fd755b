"""The compiled steps behind the Gymnasium and SB3 layers, and the precision scope they run in.

A scene is split once into its array leaves and its static rest. The jitted functions
take the leaves, packed into one vector of the layer's dtype (float64 by default, as
Gymnasium computes; float32 on request), as an argument (so a changed physical
parameter needs no recompile) and close over the static rest; they are cached by that
rest, so every env of the same configuration (`check_env` and `make_vec` build several)
shares one compilation. This avoids `eqx.filter_jit`, whose per-call partitioning would
dominate a step this small; and every argument and result of a jitted call costs a few
microseconds of dispatch, as much as a whole batched CartPole step, hence the packing of
the results into few arrays.

Every function steps through `AbstractEnv.advance` (the step semantics), `truncate`
(the time limit) and `observation`; what the layer adds is Gymnasium's float32
observation (`layer_advance`).
"""

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..env import AbstractEnv, EnvState, step_keys
from ..scenes import make
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
        return make(scene_cls, **kwargs)


class Compiled(NamedTuple):
    """The jitted functions of one scene configuration. Each takes the packed parameters
    first (the batched ones: one vector shared by all envs, or one row per env) and the
    carried key (None for a deterministic scene) among its arguments, and returns the key
    to carry next.

    - `step(parameters, inputs, key) -> (outcome, key)`: one env from `inputs`, the
      action, step count and state packed by `pack_step`; `outcome` packs the next state,
      the float32 observation, the reward, terminated, `solver_ok`, `solver_steps` and
      `action_ok` (`unpack_step`).
    - `observe(parameters, y, steps, key) -> (observation, key)`: one env's float32 observation.
    - `batch_observe(parameters, y, steps, key) -> (observation, key)`: all envs'.
    - `batch_advance(parameters, y, steps, action, key, observation) -> (y, steps,
      observation, outcome, key)`: all envs step (`observation`, the observation of `y`
      returned last, is what a failed step returns again); `outcome` has one row each for
      the reward, terminated, truncated (`AbstractEnv.truncate`), `solver_ok` and
      `solver_steps` (not `action_ok`: the front ends refuse an inadmissible action before
      the step, so it is always True there).
    - `batch_advance_or_restart(..., observation, mask, starts)`: as `batch_advance`,
      except that the envs of `mask` restart from `starts` instead of stepping, with
      their fresh observation, reward 0, no end (Gymnasium's next-step autoreset). One
      compilation serves every pattern of restarts.
    - `batch_restart(parameters, y, steps, key, observation, mask, starts) -> (y, steps,
      observation, key)`: the envs of `mask` restart from `starts` (same-step autoreset,
      a masked reset).
    - `batch_advance_then_restart(parameters, y, steps, action, key, observation, starts)
      -> (y, steps, observation, summary, key)`: SB3's same-step autoreset in one call.
      Every env steps, and those whose episode ended restart from their row of `starts`
      (drawn before the step), as `batch_restart` of them would (with `starts` None, they
      are left ended); the key moves on only if some env restarted, as it does when
      `batch_restart` is called only then. `summary` is what the host reads of the step,
      one float32 vector (`unpack_vec_step`).
    """

    step: Callable
    observe: Callable
    batch_observe: Callable
    batch_advance: Callable
    batch_advance_or_restart: Callable
    batch_restart: Callable
    batch_advance_then_restart: Callable


class SplitScene:
    """A scene as packed parameters and a static rest, with its `Compiled` functions.

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
            # An integer leaf (the time limit) built in float64 is int64, which a float32 scope
            # cannot hold: its dtype there is the scope's own (int32), which JAX would truncate
            # it to anyway, with a warning on every trace.
            canonical = jax.dtypes.canonicalize_dtype
            layout = tuple(
                (leaf.shape, real if jnp.issubdtype(leaf.dtype, jnp.floating) else canonical(leaf.dtype))
                for leaf in leaves
            )
            flat = [jnp.ravel(leaf).astype(real) for leaf in leaves]
            self.parameters = jnp.concatenate([*flat, jnp.zeros(0, real)])
        self.scene = scene
        self.compiled: Compiled = _functions(treedef, static, layout)

    def precision(self):
        # `precision(self.dtype)` without checking the dtype again: this is on every step.
        return jax.enable_x64(self.dtype == "float64")

    def key(self, seed: int) -> jax.Array | None:
        if not self.scene.stochastic:
            return None
        with self.precision():
            return jr.key(int(seed) % 2**32)

    def carried_key(self, key: jax.Array | None) -> jax.Array | None:
        """The key to carry on with under this scene: `key` if the scene is stochastic
        (a parameter write does not restart it), a fresh one if it had none, else None."""
        if not self.scene.stochastic:
            return None
        return self.key(0) if key is None else key


class HostArray:
    """A JAX array (or key array) on the host, for pickling: a process without float64
    enabled loads it back in its own dtype."""

    def __init__(self, value: jax.Array):
        self.is_key = jnp.issubdtype(value.dtype, jax.dtypes.prng_key)
        self.implementation = str(jax.random.key_impl(value)) if self.is_key else None
        self.data = np.asarray(jax.random.key_data(value) if self.is_key else value)


def to_host(value):
    """`value` with its JAX arrays as `HostArray`s (a pytree map)."""
    return jax.tree.map(lambda x: HostArray(x) if isinstance(x, jax.Array) else x, value)


def to_device(value):
    """The inverse of `to_host`, in float64."""

    def load(x):
        if not isinstance(x, HostArray):
            return x
        if x.is_key:
            return jr.wrap_key_data(jnp.asarray(x.data), impl=x.implementation)
        return jnp.asarray(x.data)

    with float64():
        return jax.tree.map(load, value, is_leaf=lambda x: isinstance(x, HostArray))


def to_numpy(array: jax.Array) -> np.ndarray:
    """A NumPy copy of `array`, taken through the buffer protocol where JAX offers it (an
    array on the CPU; it waits for the array as `np.array` does): this skips the Python
    layers of `jax.Array.__array__`, about half of what a copy of a small result costs
    (measured: 1.8 us against 3.7 us over the call, for 73 floats). Elsewhere (an
    accelerator's array), `np.array`."""
    try:
        view = memoryview(array)  # type: ignore[arg-type]  # jax.Array does not declare the protocol
    except Exception:  # no buffer: `np.array` copies it, or raises what is wrong with it
        return np.array(array)
    return np.array(view)


def pack_step(y: np.ndarray, steps: int, action) -> np.ndarray:
    """The inputs of `Compiled.step` as one float64 array: one host-to-device transfer."""
    return np.concatenate([np.ravel(action), [steps], y], dtype=np.float64)


class StepOutcome(NamedTuple):
    """`Compiled.step`'s packed outcome, unpacked on the host."""

    state: np.ndarray
    observation: np.ndarray
    reward: float
    terminated: bool
    solver_ok: bool
    solver_steps: int
    action_ok: bool


class VecStep(NamedTuple):
    """`Compiled.batch_advance_then_restart`'s summary, unpacked on the host: what SB3's
    `VecEnv.step` returns of it, each a new array (or list) of its own."""

    observation: np.ndarray
    """float32, shape `(num_envs, *observation shape)`: the next episode's first for the envs that restarted."""
    final_observation: np.ndarray
    """float32, the step's own observation (before any restart)."""
    reward: np.ndarray
    """float32, as SB3's VecEnvs return it."""
    done: np.ndarray
    """bool: terminated or truncated."""
    time_limit: list[bool]
    """Truncated and not terminated (SB3's `TimeLimit.truncated`)."""
    solver_ok: list[bool]
    solver_steps: list[int]
    admissible: bool
    """Whether every action could be applied; if not, the front end refuses the step."""


def unpack_vec_step(summary: jax.Array, observation_shape: tuple[int, ...]) -> VecStep:
    num_envs = observation_shape[0]
    size = math.prod(observation_shape)
    # One copy off the device; the parts are views of it, so each is an array of its own.
    host = to_numpy(summary)
    rows = host[2 * size : -1].reshape(5, num_envs)
    flags = rows[1:4] != 0  # done, time limit, solver_ok: one NumPy call, and Python bools by `tolist`
    time_limit, solver_ok = flags[1:].tolist()
    return VecStep(
        host[:size].reshape(observation_shape), host[size : 2 * size].reshape(observation_shape),
        rows[0], flags[0], time_limit, solver_ok, rows[4].astype(np.int64).tolist(), bool(host[-1]),
    )


def unpack_step(outcome: np.ndarray, state_size: int, observation_size: int) -> StepOutcome:
    n, m = state_size, observation_size
    reward, terminated, solver_ok, solver_steps, action_ok = outcome[n + m :].tolist()
    # The observation was computed in float32; the float64 round trip is exact.
    return StepOutcome(
        outcome[:n].copy(), outcome[n : n + m].astype(np.float32), float(reward), bool(terminated),
        bool(solver_ok), int(solver_steps), bool(action_ok),
    )


def _cache(function: Callable) -> Callable:
    cached = functools.lru_cache(maxsize=64)(function)

    @functools.wraps(function)
    def wrapper(*args):
        try:
            return cached(*args)
        except TypeError:  # an unhashable static part: compile for this env alone
            return function(*args)

    return wrapper


def layer_advance(scene: AbstractEnv, y, steps, action, key, previous):
    """`scene.advance` with the float32 observation Gymnasium returns: `(y, steps,
    observation, reward, terminated, info)`, `previous` being the float32 observation of `y`.

    The two halves of `advance`, with the cast between them: a finite float64 state can
    still overflow float32's range in the observation, and `conclude` checks the float32
    observation, so such a step fails by `advance`'s own rule (pre-step state, `previous`,
    the worst reward, terminated) and nothing non-finite reaches an agent. Passing
    `previous` (which the layer holds) spares observing `y` again, a second observation
    per step.
    """
    state = EnvState(y=y, steps=steps)
    trial = scene.attempt(state, action, key=key)
    trial = trial._replace(observation=trial.observation.astype(jnp.float32))
    state, observation, reward, terminated, info = scene.conclude(state, trial, previous, key=key)
    return state.y, state.steps, observation, reward, terminated, info


@_cache
def _functions(treedef, static, layout) -> Compiled:
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

    def observe_one(scene, y, steps, key):
        key = step_keys(key, scene.stochastic).observation
        return scene.observation(EnvState(y=y, steps=steps), key=key).astype(jnp.float32)

    def env_axis(parameters):
        # One vector shared by every env (the common case: the scene's leaves are not
        # batched, so the step costs what a single scene's does), or one row per env.
        return 0 if parameters.ndim == 2 else None

    def observe_all(parameters, y, steps, key):
        key, keys = next_key(key, num_envs=y.shape[0])
        observe = lambda p, *rest: observe_one(scene_of(p), *rest)  # noqa: E731
        return jax.vmap(observe, in_axes=(env_axis(parameters), 0, 0, 0))(parameters, y, steps, keys), key

    def advance_all(parameters, y, steps, action, key, observation):
        key, keys = next_key(key, num_envs=y.shape[0])
        axis = env_axis(parameters)
        advance = lambda p, *rest: layer_advance(scene_of(p), *rest)  # noqa: E731
        y, steps, observation, reward, terminated, info = jax.vmap(advance, in_axes=(axis, 0, 0, 0, 0, 0))(
            parameters, y, steps, action, keys, observation
        )
        truncate = lambda p, state: scene_of(p).truncate(state)  # noqa: E731
        truncated = jax.vmap(truncate, in_axes=(axis, 0))(parameters, EnvState(y=y, steps=steps))
        return y, steps, observation, (reward, terminated, truncated, info), key

    def outcome_rows(reward, terminated, truncated, info):
        # One array for the host besides the observation: a row each (rows of it are
        # contiguous arrays on the host).
        rows = (reward, terminated, truncated, info["solver_ok"], info["solver_steps"])
        return jnp.stack([jnp.astype(x, reward.dtype) for x in rows])

    def restart(parameters, y, steps, key, observation, mask, starts):
        y = jnp.where(mask[:, None], starts, y)
        steps = jnp.where(mask, 0, steps)
        fresh, key = observe_all(parameters, starts, steps, key)
        return y, steps, jnp.where(mask[:, None], fresh, observation), key

    @jax.jit
    def step(parameters, inputs, key):
        scene = scene_of(parameters)
        space = scene.action_space
        size = math.prod(space.shape)
        action = inputs[:size].reshape(space.shape)
        if isinstance(space, Discrete):
            action = action.astype(int)
        steps, y = inputs[size].astype(int), inputs[size + 1 :]
        key, step_key = next_key(key)
        previous = observe_one(scene, y, steps, None if step_key is None else jr.fold_in(step_key, 5))
        y, _, observation, reward, terminated, info = layer_advance(scene, y, steps, action, step_key, previous)
        rows = (reward, terminated, info["solver_ok"], info["solver_steps"], info["action_ok"])
        rows = jnp.stack([jnp.astype(x, y.dtype) for x in rows])
        return jnp.concatenate([y, observation.astype(y.dtype), rows]), key

    @jax.jit
    def observe(parameters, y, steps, key):
        key, observation_key = next_key(key)
        return observe_one(scene_of(parameters), y, steps, observation_key), key

    @jax.jit
    def batch_observe(parameters, y, steps, key):
        return observe_all(parameters, y, steps, key)

    @jax.jit
    def batch_advance(parameters, y, steps, action, key, observation):
        y, steps, observation, outcome, key = advance_all(parameters, y, steps, action, key, observation)
        return y, steps, observation, outcome_rows(*outcome), key

    @jax.jit
    def batch_advance_or_restart(parameters, y, steps, action, key, observation, mask, starts):
        y, steps, observation, (reward, terminated, truncated, info), key = advance_all(
            parameters, y, steps, action, key, observation
        )
        y, steps, observation, key = restart(parameters, y, steps, key, observation, mask, starts)
        reward = jnp.where(mask, 0, reward)
        info = {
            "solver_ok": info["solver_ok"] | mask,
            "solver_steps": jnp.where(mask, 0, info["solver_steps"]),
        }
        return y, steps, observation, outcome_rows(reward, terminated & ~mask, truncated & ~mask, info), key

    @jax.jit
    def batch_restart(parameters, y, steps, key, observation, mask, starts):
        return restart(parameters, y, steps, key, observation, mask, starts)

    @jax.jit
    def batch_advance_then_restart(parameters, y, steps, action, key, observation, starts):
        y, steps, final, (reward, terminated, truncated, info), key = advance_all(
            parameters, y, steps, action, key, observation
        )
        done = terminated | truncated
        observation = final
        if starts is not None:  # a second compilation for None, which few callers use
            y, steps, observation, restarted_key = restart(parameters, y, steps, key, final, done, starts)
            if key is not None and restarted_key is not None:  # both, for a stochastic scene
                key = jax.lax.select(jnp.any(done), restarted_key, key)
        # float32 holds every entry exactly: the observations are float32, the flags 0 or 1,
        # the step counts below 2**24 (their budget, `max_steps`: 4096 by default); the reward
        # is rounded as SB3 rounds it.
        summary = [
            observation, final, reward, done, truncated & ~terminated, info["solver_ok"], info["solver_steps"],
            jnp.all(info["action_ok"]),
        ]
        return y, steps, observation, jnp.concatenate([jnp.ravel(x).astype(jnp.float32) for x in summary]), key

    return Compiled(
        step, observe, batch_observe, batch_advance, batch_advance_or_restart, batch_restart,
        batch_advance_then_restart,
    )
