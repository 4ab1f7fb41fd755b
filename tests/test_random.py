"""Random starts: the 16-bit uniform draws, and which parts of an env get which key."""

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
import scipy.stats

import lerax_like as ll
from lerax_like._random import uniform


@pytest.mark.parametrize("impl", ["threefry2x32", "rbg"])
def test_uniform_draws_are_uniform_independent_and_on_the_16_bit_grid(impl):
    n = 20_000
    keys = jr.split(jr.key(0, impl=impl), n)
    low, high = jnp.array([-0.05, -3.0, 0.0, 2.0, -1.0]), jnp.array([0.05, 3.0, 1.0, 2.5, 1.0])
    draws = np.asarray(jax.vmap(lambda key: uniform(key, (5,), jnp.float64, low, high))(keys))
    low, high = np.asarray(low), np.asarray(high)

    fraction = (draws - low) / (high - low)
    assert np.all((fraction >= 0) & (fraction < 1))
    grid = fraction * 65536
    np.testing.assert_allclose(grid, np.round(grid), atol=1e-6)
    for column in fraction.T:  # each coordinate uniform (Kolmogorov-Smirnov)
        assert scipy.stats.kstest(column, "uniform").pvalue > 1e-3
    # Coordinates uncorrelated, including the fifth, which comes from a second hash.
    correlation = np.corrcoef(fraction.T) - np.eye(5)
    assert np.max(np.abs(correlation)) < 5 / np.sqrt(n)


def test_uniform_shapes_and_dtypes():
    assert uniform(jr.key(0), (), jnp.float32, -0.6, -0.4).shape == ()
    assert uniform(jr.key(0), (2, 3), jnp.float32, 0.0, 1.0).dtype == jnp.float32
    draws = uniform(jr.key(1), (9,), jnp.float64, 0.0, 1.0)
    assert len(np.unique(np.asarray(draws))) == 9


class _Drift(ll.AbstractDynamics):
    velocity_indices = None

    def vector_field(self, t, y, u):
        return u


class _NoisyObservation(ll.AbstractEnv):
    """Sees its state through noise drawn with the observation's key."""

    stochastic = True

    dynamics: _Drift
    integrator: ll.Integrator
    dt: jax.Array
    max_episode_steps: int = 1

    @property
    def action_space(self):
        return ll.Box(-1.0, 1.0, (1,))

    @property
    def observation_space(self):
        return ll.Box(-jnp.inf, jnp.inf, (1,))

    @property
    def initial_bounds(self):
        # Unused by its Gaussian start (`initial`), but they give the state's shape.
        return jnp.zeros(1), jnp.zeros(1)

    def initial(self, *, key):
        return ll.EnvState(y=jr.normal(key, (1,)), steps=jnp.zeros((), dtype=int))

    def physical_input(self, action):
        return action

    def observation(self, state, *, key):
        return state.y + jr.normal(key, (1,))

    def reward(self, state, action, next_state, *, key):
        return jnp.zeros(())

    @property
    def worst_reward(self):
        return jnp.zeros(())

    def terminal(self, state, *, key):
        return jnp.asarray(False)


class _DeclaredDeterministic(_NoisyObservation):
    stochastic = False


def _noisy(cls):
    return cls(_Drift(), ll.make_integrator("euler"), jnp.asarray(0.1))


def test_a_stochastic_env_gives_every_part_its_own_key():
    # Start and observation noise from independent keys: over many resets the noise is
    # uncorrelated with the start (with one key reused both would be the same draw).
    env = _noisy(_NoisyObservation)
    states, observations, _ = jax.vmap(lambda key: env.reset(key=key))(jr.split(jr.key(0), 4000))
    start, noise = np.asarray(states.y[:, 0]), np.asarray(observations[:, 0] - states.y[:, 0])
    assert abs(np.corrcoef(start, noise)[0, 1]) < 5 / np.sqrt(4000)
    # The same for the restart inside `step` (the time limit is one step, so every env
    # restarts), whose start must also differ from the pre-step draws.
    step = jax.vmap(lambda state, key: env.step(state, jnp.zeros(1), key=key))
    restarted, observation, _, _, truncated, _ = step(states, jr.split(jr.key(1), 4000))
    assert bool(jnp.all(truncated))
    start, noise = np.asarray(restarted.y[:, 0]), np.asarray(observation[:, 0] - restarted.y[:, 0])
    assert abs(np.corrcoef(start, noise)[0, 1]) < 5 / np.sqrt(4000)
    assert np.std(noise) > 0.9


def test_a_part_that_draws_in_an_env_declared_deterministic_fails_at_once():
    env = _noisy(_DeclaredDeterministic)
    with pytest.raises(TypeError, match="PRNG key type .*NoneType"):
        env.reset(key=jr.key(0))


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_policy_return_gives_a_stochastic_env_its_keys():
    # A rollout through noisy observations: its return depends on the key (a
    # deterministic env's parts would get no key at all and fail here).
    from lerax_like.control.learning import policy_return

    env = _noisy(_NoisyObservation)
    state = ll.EnvState(y=jnp.zeros(1), steps=jnp.zeros((), dtype=int))

    def observed_drift(key):
        return policy_return(env, lambda observation: observation, state, 50, key=key,
                             state_cost=lambda y: -y[0])  # reward = the state: sums the drift

    first, second = observed_drift(jr.key(0)), observed_drift(jr.key(1))
    assert np.isfinite(float(first)) and float(first) != float(second)
