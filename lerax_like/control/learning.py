"""Control by differentiating through the simulator: policy learning and trajectory optimisation.

The env's steps are diffrax solves, so a return summed along a rollout is a differentiable
function of the policy's weights, of a force sequence, or of the physical parameters.
`train_policy` maximises it by gradient ascent over a batch of vmapped envs (each env of
the batch may carry its own physical parameters: domain randomisation), and
`train_policy_curriculum` does so in stages of growing horizon; `episode_lengths` counts
how long a policy keeps episodes alive.
"""

import functools
from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

from .._types import Array, ArrayLike, Float, Int, Key
from ..env import AbstractEnv, EnvState, rollout, step_keys


def _optax():
    try:
        import optax
    except ImportError as error:  # pragma: no cover
        raise ImportError("policy training needs optax: pip install optax") from error
    return optax


class MLPPolicy(eqx.Module):
    """A deterministic policy: an MLP from observation to action, squashed into `[-1, 1]` by tanh."""

    mlp: eqx.nn.MLP

    def __init__(self, observation_size: int, action_size: int, *, width: int = 32, depth: int = 2, key: Key):
        self.mlp = eqx.nn.MLP(observation_size, action_size, width, depth, activation=jnp.tanh, key=key)

    def __call__(self, observation: Float[Array, " n"]) -> Float[Array, " m"]:
        return jnp.tanh(self.mlp(observation))


def policy_return(
    env: AbstractEnv,
    policy: Callable,
    state: EnvState,
    horizon: int,
    *,
    key: Key,
    state_cost: Callable[[Array], Array] | None = None,
    rewarded_steps: Int[ArrayLike, ""] | None = None,
) -> Float[Array, ""]:
    """The sum of rewards of `horizon` transitions under `policy` (no termination, no reset).

    `state_cost(y)`, if given, is subtracted from each step's reward (`y` the next state).
    `rewarded_steps`, if given (it may be traced), sums only the first that many rewards:
    one compiled rollout then serves every horizon up to `horizon`.
    """

    def body(state, step_key):
        # The observation before the step under that key's observation part, as `step`
        # derives them (none for a deterministic env); then the step itself.
        observation = env.observation(state, key=step_keys(step_key, env.stochastic).observation)
        action = policy(observation)
        next_state, _, reward, _, _ = env.advance(state, action, key=step_key)
        if state_cost is not None:
            reward = reward - state_cost(next_state.y)
        return next_state, reward

    keys = jr.split(key, horizon) if env.stochastic else None
    _, rewards = jax.lax.scan(body, state, keys, length=horizon)
    if rewarded_steps is not None:
        rewards = jnp.where(jnp.arange(horizon) < rewarded_steps, rewards, jnp.zeros_like(rewards))
    return jnp.sum(rewards)


def train_policy(
    envs: AbstractEnv,
    policy,
    *,
    key: Key,
    num_envs: int,
    horizon: int,
    iterations: int,
    learning_rate: float = 3e-3,
    initial_spread: float | Float[Array, " n"] = 0.2,
    env_axis: int | None = None,
    state_cost: Callable[[Array], Array] | None = None,
):
    """Gradient ascent on the mean return of `num_envs` vmapped rollouts of `horizon` steps.

    Each iteration draws fresh initial states uniform in `(-initial_spread, initial_spread)`
    (wider than the env's own start, so that the policy sees recoveries; an array gives
    one spread per state coordinate). `envs` is one env (`env_axis=None`) or a batch of
    `num_envs` envs along axis 0 (`env_axis=0`), say with per-env pole masses. Adam with
    the gradient norm clipped at 1: backpropagating through an unstable system makes
    occasional huge gradients.

    `state_cost(y)`, if given, is subtracted from every step's reward during training
    (see `policy_return`). CartPole's smooth reward is indifferent to where the cart is:
    a policy that keeps the pole up but is trained too briefly lets the cart drift out of
    the 2.4 m track within the 10 s of an episode.

    Returns the trained policy and the mean return per iteration.
    """
    policy, (history,) = _train_in_stages(
        envs, policy, (key,), (horizon,), (iterations,), (learning_rate,),
        num_envs=num_envs, initial_spread=initial_spread, env_axis=env_axis, state_cost=state_cost,
    )
    return policy, history


def train_policy_curriculum(
    envs: AbstractEnv,
    policy,
    *,
    key: Key,
    num_envs: int,
    horizons: Sequence[int],
    iterations: Sequence[int],
    learning_rates: Sequence[float],
    initial_spread: float | Float[Array, " n"] = 0.2,
    env_axis: int | None = None,
    state_cost: Callable[[Array], Array] | None = None,
):
    """`train_policy` in stages of growing horizon, each stage starting from the last one's policy.

    Stage `i` runs `iterations[i]` Adam steps (from a fresh optimiser state) on rollouts of
    `horizons[i]` steps at `learning_rates[i]`; the other arguments are `train_policy`'s.
    Why stages: from an untrained policy the pole falls within the first second, and the
    return of a long rollout is then dominated by a swinging pendulum whose gradient
    carries little about how to catch it (on CartPoleContinuous with a cost on the cart,
    100-step rollouts from scratch stalled at a mean reward of 0.5 a step for 4 seeds of
    4). A short horizon teaches the catch; once the closed loop is stable, long rollouts
    no longer end in a swinging pendulum, and their gradient teaches what shows only over
    seconds (a slowly growing oscillation, the cart's drift).

    All stages run one compiled update: rollouts are `max(horizons)` steps long and a
    stage counts the rewards of its first `horizons[i]` steps (on CartPoleContinuous the
    extra steps cost less than the compilations they save).

    Returns the trained policy and a tuple with each stage's mean return per iteration.
    """
    if not len(horizons) == len(iterations) == len(learning_rates):
        raise ValueError(
            "horizons, iterations and learning_rates must have one entry per stage, got "
            f"{len(horizons)}, {len(iterations)} and {len(learning_rates)}"
        )
    return _train_in_stages(
        envs, policy, tuple(jr.split(key, len(horizons))), tuple(horizons), tuple(iterations),
        tuple(learning_rates), num_envs=num_envs, initial_spread=initial_spread, env_axis=env_axis,
        state_cost=state_cost,
    )


@functools.cache
def _optimiser():
    optax = _optax()
    # Adam without its learning rate, which `_update` takes as an argument: one optimiser
    # object (static to the jit) and so one compilation for every learning rate.
    return optax.chain(optax.clip_by_global_norm(1.0), optax.scale_by_adam())


def _train_in_stages(envs, policy, keys, horizons, iterations, learning_rates, *, num_envs, initial_spread, env_axis, state_cost):
    params, static = eqx.partition(policy, eqx.is_inexact_array)
    state_size = eqx.filter_eval_shape(lambda env: env.initial(key=jr.key(0)).y, envs).shape[-1]
    initial_spread = jnp.asarray(initial_spread)
    histories = []
    for stage_key, horizon, stage_iterations, learning_rate in zip(keys, horizons, iterations, learning_rates):
        opt_state = _optimiser().init(params)
        history = []
        for iteration_key in jr.split(stage_key, stage_iterations):
            params, opt_state, value = _update(
                params, opt_state, iteration_key, jnp.asarray(horizon), jnp.asarray(learning_rate),
                static, envs, initial_spread, num_envs=num_envs, state_size=state_size,
                rollout_steps=max(horizons), env_axis=env_axis, state_cost=state_cost,
            )
            history.append(value)
        histories.append(jnp.stack(history))
    return eqx.combine(params, static), tuple(histories)


@eqx.filter_jit
def _update(params, opt_state, key, horizon, learning_rate, static, envs, initial_spread, *, num_envs, state_size, rollout_steps, env_axis, state_cost):
    def mean_return(params):
        policy = eqx.combine(params, static)
        start_key, rollout_key = jr.split(key)
        ys = jr.uniform(start_key, (num_envs, state_size), minval=-initial_spread, maxval=initial_spread)
        states = EnvState(y=ys, steps=jnp.zeros((num_envs,), dtype=int))
        returns = eqx.filter_vmap(
            lambda env, state, key: policy_return(
                env, policy, state, rollout_steps, key=key, state_cost=state_cost, rewarded_steps=horizon
            ),
            in_axes=(env_axis, 0, 0),
        )(envs, states, jr.split(rollout_key, num_envs))
        return jnp.mean(returns)

    value, grads = jax.value_and_grad(lambda p: -mean_return(p))(params)
    optax = _optax()
    # optax's bias correction mixes a float decay with an int32 count, which strict
    # dtype promotion (as in our tests) refuses; the env's own code stays strict.
    with jax.numpy_dtype_promotion("standard"):
        updates, opt_state = _optimiser().update(grads, opt_state, params)
        updates = jax.tree.map(lambda update: -learning_rate * update, updates)
        params = optax.apply_updates(params, updates)
    return params, opt_state, -value


def episode_lengths(env: AbstractEnv, policy: Callable, *, key: Key, num_starts: int, max_steps: int = 500) -> Array:
    """Steps each of `num_starts` episodes from the env's random starts lasts under `policy`, capped at `max_steps`.

    Uses `env.step`, so the env's own termination (angle and position thresholds) ends
    an episode; a truncation does not (its autoreset is ignored past the cap). The env
    and the policy are arguments of one jitted function, so evaluating the same policy
    on envs that differ only in their parameters (a sweep over pole masses) compiles once.
    """
    return _episode_lengths(env, policy, jr.split(key, num_starts), max_steps)


@eqx.filter_jit
def _episode_lengths(env: AbstractEnv, policy: Callable, keys: Key, max_steps: int) -> Array:
    def one(key):
        reset_key, step_key = jr.split(key)
        state, observation, _ = env.reset(key=reset_key)

        def body(carry, key):
            state, observation, alive, length = carry
            state, observation, _, terminated, _, _ = env.step(state, policy(observation), key=key)
            length = length + alive.astype(length.dtype)
            alive = alive & ~terminated
            return (state, observation, alive, length), None

        carry = (state, observation, jnp.asarray(True), jnp.zeros((), dtype=int))
        (_, _, _, length), _ = jax.lax.scan(body, carry, jr.split(step_key, max_steps))
        return length

    return jax.vmap(one)(keys)


def optimise_open_loop(
    env: AbstractEnv,
    y0: Float[Array, " n"],
    objective: Callable[[Float[Array, "T n"]], Array],
    *,
    horizon: int,
    action_size: int,
    iterations: int,
    key: Key,
    learning_rate: float = 0.05,
) -> tuple[Float[Array, "T m"], Array]:
    """Trajectory optimisation: an action sequence minimising `objective(ys)` by Adam.

    Actions are `tanh(z)` (inside the action box `[-1, 1]`, so no clip kills the
    gradient) with `z` started small and random; the learning rate decays by a cosine
    schedule to 5% of `learning_rate`. Returns the actions and the objective per iteration.
    """
    optax = _optax()
    optimiser = optax.adam(optax.cosine_decay_schedule(learning_rate, iterations, 0.05))
    start = EnvState(y=y0, steps=jnp.zeros((), dtype=int))

    def loss(z):
        return objective(rollout_states(env, start, jnp.tanh(z)))

    @eqx.filter_jit
    def update(z, opt_state):
        value, grad = jax.value_and_grad(loss)(z)
        with jax.numpy_dtype_promotion("standard"):
            updates, opt_state = optimiser.update(grad, opt_state, z)
            z = jnp.asarray(optax.apply_updates(z, updates))  # optax types its result as any pytree
        return z, opt_state, value

    z = 0.1 * jr.normal(key, (horizon, action_size), dtype=y0.dtype)
    opt_state = optimiser.init(z)
    history = []
    for _ in range(iterations):
        z, opt_state, value = update(z, opt_state)
        history.append(value)
    return jnp.tanh(z), jnp.stack(history)


def rollout_states(env: AbstractEnv, state: EnvState, actions: Array) -> Float[Array, "T n"]:
    """The states after each of `actions` (`lerax_like.rollout` without the info)."""
    return rollout(env, state, actions, key=jr.key(0))[0]
