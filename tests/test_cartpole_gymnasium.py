"""CartPole with explicit Euler reproduces Gymnasium's CartPole-v1, driven by Gymnasium itself."""

import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.env import EnvState


def _balancing_action(state: np.ndarray) -> int:
    x, x_dot, theta, theta_dot = state
    return int(theta + 0.5 * theta_dot + 0.05 * x + 0.1 * x_dot > 0)


@pytest.fixture(scope="module")
def one_step():
    @jax.jit
    def step(env, y, action, key):
        next_state, info = env.transition(EnvState(y=y, steps=jnp.zeros((), int)), action, key=key)
        terminated = env.terminal(next_state, key=key)
        return next_state.y, terminated, info["solver_ok"]

    return step


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_step_from_gymnasium_state_over_balanced_episodes(seed, one_step):
    reference = gymnasium.make("CartPole-v1")
    env = ll.make("CartPole", solver="euler")
    key = jax.random.key(seed)
    observation, _ = reference.reset(seed=seed)
    rng = np.random.default_rng(seed)
    steps = 0
    truncated = terminated = False
    while not (terminated or truncated):
        state = np.array(reference.unwrapped.state, dtype=np.float64)
        # Mostly balance, sometimes push at random, so the pole does move about.
        action = _balancing_action(state) if rng.random() > 0.2 else int(rng.integers(2))
        observation, reward, terminated, truncated, _ = reference.step(action)
        expected = np.asarray(reference.unwrapped.state, dtype=np.float64)
        y, our_terminated, ok = one_step(env, jnp.asarray(state), jnp.asarray(action), key)
        np.testing.assert_allclose(np.asarray(y), expected, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(np.asarray(y, dtype=np.float32), observation)
        assert bool(our_terminated) == terminated
        assert bool(ok)
        assert reward == 1.0
        steps += 1
    # A whole balanced episode: the time limit ends it, not the pole.
    assert truncated and not terminated and steps == 500


@pytest.mark.filterwarnings("ignore:.*already returned terminated")
def test_free_running_100_steps():
    reference = gymnasium.make("CartPole-v1")
    reference.reset(seed=3)
    y0 = np.array(reference.unwrapped.state, dtype=np.float64)
    rng = np.random.default_rng(3)
    actions = rng.integers(0, 2, size=100)
    expected = []
    for action in actions:
        reference.unwrapped.step(int(action))  # unwrapped: run on past termination as pure physics
        expected.append(np.array(reference.unwrapped.state, dtype=np.float64))
    env = ll.make("CartPole", solver="euler")
    ys, infos = eqx.filter_jit(ll.rollout)(
        env, EnvState(y=jnp.asarray(y0), steps=jnp.zeros((), int)), jnp.asarray(actions), key=jax.random.key(0)
    )
    expected = np.stack(expected)
    error = np.max(np.abs(np.asarray(ys) - expected) / np.maximum(np.abs(expected), 1.0))
    assert error < 1e-9
    assert np.all(np.asarray(infos["solver_ok"]))


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_step_matches_gymnasium_episode_with_autoreset():
    """The full `step` (reward, termination, autoreset) against a Gymnasium episode."""
    reference = gymnasium.make("CartPole-v1")
    env = ll.CartPole()
    step = eqx.filter_jit(env.step)
    reference.reset(seed=11)
    state = EnvState(y=jnp.asarray(reference.unwrapped.state, dtype=float), steps=jnp.zeros((), int))
    rng = np.random.default_rng(11)
    keys = jax.random.split(jax.random.key(11), 600)
    for t in range(600):
        action = int(rng.integers(2))
        observation, reward, terminated, truncated, _ = reference.step(action)
        state, our_observation, our_reward, our_terminated, our_truncated, info = step(
            state, jnp.asarray(action), key=keys[t]
        )
        np.testing.assert_allclose(np.asarray(info["final_observation"]), observation, rtol=1e-6, atol=1e-7)
        assert float(our_reward) == reward
        assert bool(our_terminated) == terminated and bool(our_truncated) == truncated
        if terminated or truncated:
            # Our autoreset drew a fresh episode; restart Gymnasium from the same state.
            assert int(state.steps) == 0 and np.all(np.abs(np.asarray(state.y)) <= 0.05)
            reference.reset()
            reference.unwrapped.state = np.array(state.y, dtype=np.float64)
            return
    pytest.fail("a random policy should end a CartPole episode within 600 steps")
