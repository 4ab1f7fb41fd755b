"""Policy learning through the simulator (the notebook `policy_learning.ipynb`)."""

import jax.numpy as jnp
import jax.random as jr

import lerax_like as ll
from lerax_like.control.learning import MLPPolicy, episode_lengths, policy_return, train_policy
from lerax_like.env import EnvState

from conftest import relative_error


def test_policy_trained_on_smooth_reward_balances_for_500_steps():
    inf = float("inf")
    train_env = ll.CartPoleContinuous(reward="smooth", theta_threshold_radians=inf, x_threshold=inf)
    policy, history = train_policy(
        train_env, MLPPolicy(4, 1, width=32, key=jr.key(0)), key=jr.key(1),
        num_envs=1024, horizon=100, iterations=100, learning_rate=3e-3,
    )
    assert float(history[-1]) > float(history[0])
    # Different starts from the notebook's: 100 episodes of the ordinary env.
    lengths = episode_lengths(ll.CartPoleContinuous(), policy, key=jr.key(7), num_starts=100, max_steps=500)
    assert float(jnp.mean(lengths >= 500)) >= 0.95


def test_rewarded_steps_count_the_first_rewards_of_a_longer_rollout():
    # What lets every stage of train_policy_curriculum share one compiled update.
    inf = float("inf")
    env = ll.CartPoleContinuous(reward="smooth", theta_threshold_radians=inf, x_threshold=inf)
    policy = MLPPolicy(4, 1, width=8, key=jr.key(0))
    state = EnvState(y=jnp.array([0.1, 0.0, 0.15, -0.1]), steps=jnp.zeros((), dtype=int))
    short = policy_return(env, policy, state, 20, key=jr.key(1))
    masked = policy_return(env, policy, state, 60, key=jr.key(1), rewarded_steps=jnp.asarray(20))
    assert relative_error(masked, short) < 1e-13
