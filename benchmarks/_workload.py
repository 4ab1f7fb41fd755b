"""The shared benchmark workload: N CartPoles, random actions, autoreset, T steps in one scan.

Every JAX implementation is measured on the same program: a `lax.scan` over `T` steps
whose body splits the carried key, draws a random action (0 or 1) and calls the env's
step with autoreset, `jax.vmap`-ed over `N` independent envs. The scan returns only the
summed reward and the final state, so that little leaves the device and XLA cannot drop
the physics as dead code (the same for every implementation).
"""

import statistics
import time

import jax
import jax.numpy as jnp
import jax.random as jr


def scanned(step, initial, num_steps: int):
    """`rollout(key) -> (total reward, final state)` for one env; `step(state, action, key)` and `initial(key)`.

    `step` returns `(state, reward)`; the body is identical for every implementation.
    """

    def rollout(key):
        reset_key, key = jr.split(key)
        state = initial(reset_key)

        def body(carry, _):
            state, key, total = carry
            key, action_key, step_key = jr.split(key, 3)
            action = jr.randint(action_key, (), 0, 2)
            state, reward = step(state, action, step_key)
            return (state, key, total + reward), None

        (state, _, total), _ = jax.lax.scan(body, (state, key, jnp.zeros(())), None, length=num_steps)
        # The final state leaves too: a constant reward alone would let XLA drop the physics.
        return total, state

    return rollout


def gymnax_program():
    """`(step, initial)` of gymnax's CartPole-v1 in the form `scanned` takes (gymnax imported lazily)."""
    import gymnax

    env, params = gymnax.make("CartPole-v1")

    def initial(key):
        return env.reset(key, params)[1]

    def step(state, action, key):
        _, state, reward, _, _, _ = env.step(key, state, action, params)
        return state, reward

    return step, initial


def batched(rollout, num_envs: int):
    """A jitted function of one key running `num_envs` rollouts with `jax.vmap`."""

    @jax.jit
    def run(key):
        return jax.vmap(rollout)(jr.split(key, num_envs))

    return run


def compile_seconds(run, key) -> tuple[float, object]:
    """Lower and compile `run` (a `jax.jit` function); returns seconds and the executable."""
    start = time.perf_counter()
    compiled = run.lower(key).compile()
    return time.perf_counter() - start, compiled


def time_once(fn, *args) -> float:
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - start


def interleaved(candidates: dict, repeats: int) -> dict[str, list[float]]:
    """Seconds per call of each `name -> thunk`, the candidates interleaved within each repeat.

    Interleaving spreads the noise of a shared machine over all candidates alike, so the
    ratios of their minima (or medians) are fairer than back-to-back blocks of repeats.
    """
    times = {name: [] for name in candidates}
    for _ in range(repeats):
        for name, thunk in candidates.items():
            start = time.perf_counter()
            thunk()
            times[name].append(time.perf_counter() - start)
    return times


def summary(seconds: list[float]) -> tuple[float, float]:
    return min(seconds), statistics.median(seconds)
