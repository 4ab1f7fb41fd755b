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
        # gymnax 0.0.x returns (obs, state, reward, done, info), 1.x (obs, state, reward,
        # terminated, truncated, info): the state and reward are second and third in both.
        _, state, reward, *_ = env.step(key, state, action, params)
        return state, reward

    return step, initial


# rejax's PPO configuration for CartPole-v1 (rejax's configs/gymnax/cartpole.yaml, `ppo`),
# with `env` and `env_params` given by the caller.
REJAX_CARTPOLE_PPO = {
    "agent_kwargs": {"activation": "tanh"},
    "num_envs": 5,
    "num_steps": 100,
    "num_epochs": 5,
    "num_minibatches": 5,
    "learning_rate": 0.00075,
    "max_grad_norm": 0.5,
    "total_timesteps": 100_000,
    "eval_freq": 1000,
    "gamma": 0.99,
    "gae_lambda": 0.95,
    "clip_eps": 0.2,
    "ent_coef": 0.01,
    "vf_coef": 0.5,
}


def cartpole_env(solver: str | None):
    """`(env, params)` of gymnax's CartPole-v1 (`solver=None`) or lerax_like's with `solver`."""
    if solver is None:
        import gymnax

        return gymnax.make("CartPole-v1")
    import lerax_like.gymnax

    return lerax_like.gymnax.make("CartPole-v1", solver=solver)


def rejax_ppo_training(env, params, num_seeds: int, **overrides):
    """`(train, keys)`: rejax's PPO with its CartPole config on `env`, `train(keys)` jitted and
    vmapped over `num_seeds` seeds (keys split from key 0, the same for every env).

    `train(keys)` returns rejax's `(train_state, (episode lengths, returns))`; the returns
    have shape `(num_seeds, evaluations, 128)`: rejax evaluates 128 episodes every
    `eval_freq` steps, and those evaluations draw from the train state's key without
    changing it, so `eval_freq` changes the time a run takes, not what it learns.
    """
    from rejax import PPO

    algorithm = PPO.create(env=env, env_params=params, **{**REJAX_CARTPOLE_PPO, **overrides})
    return jax.jit(jax.vmap(algorithm.train)), jr.split(jr.key(0), num_seeds)


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
