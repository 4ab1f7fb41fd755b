"""System identification from data recorded from Gymnasium's own envs: CartPole (the notebook
`sysid_cartpole.ipynb`) and Pendulum."""

import gymnasium as gym
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.control import fit_transitions


def _record(pole_mass, half_length, n, seed):
    env = gym.make("CartPole-v1").unwrapped
    env.masspole, env.length = pole_mass, half_length
    # Gymnasium caches these in __init__.
    env.total_mass = env.masspole + env.masscart
    env.polemass_length = env.masspole * env.length
    rng = np.random.default_rng(seed)
    observation, _ = env.reset(seed=seed)
    states, actions, next_states = [], [], []
    for _ in range(n):
        action = int(rng.integers(2))
        next_observation, _, terminated, truncated, _ = env.step(action)
        states.append(observation)
        actions.append(action)
        next_states.append(next_observation)
        observation = next_observation
        if terminated or truncated:
            observation, _ = env.reset()
    as64 = lambda a: jnp.asarray(np.asarray(a), dtype=jnp.float64)
    return as64(states), jnp.asarray(actions), as64(next_states)


@pytest.mark.parametrize("pole_mass, half_length", [(0.25, 0.65)])
def test_recovers_pole_mass_and_half_length_from_gymnasium(pole_mass, half_length):
    states, actions, next_states = _record(pole_mass, half_length, 100, seed=3)
    fitted, solution = fit_transitions(
        ll.CartPole(), lambda env: (env.dynamics.pole_mass, env.dynamics.half_length), states, actions, next_states
    )
    # Only the float32 rounding of Gymnasium's observations is left: measured relative errors
    # 2.2e-7 (pole mass) and 7.4e-9 (half length).
    assert abs(float(fitted.dynamics.pole_mass) / pole_mass - 1) < 1e-6
    assert abs(float(fitted.dynamics.half_length) / half_length - 1) < 5e-8


def _record_pendulum(mass, length, n, seed):
    env = gym.make("Pendulum-v1").unwrapped
    env.m, env.l = mass, length
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    states, actions, next_states = [], [], []
    for _ in range(n):
        state = np.array(env.state, dtype=np.float64)
        action = rng.uniform(-2.0, 2.0, size=(1,))  # float64: Gymnasium then computes in float64
        env.step(action)
        states.append(state)
        actions.append(action)
        next_states.append(np.array(env.state, dtype=np.float64))
    return jnp.asarray(np.stack(states)), jnp.asarray(np.stack(actions)), jnp.asarray(np.stack(next_states))


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_recovers_pendulum_mass_and_length_from_gymnasium():
    mass, length = 1.4, 0.7
    states, actions, next_states = _record_pendulum(mass, length, 100, seed=5)
    # Not vacuous: the data move, and the speed clip (non-smooth) stays inactive.
    assert np.max(np.abs(np.asarray(next_states[:, 1]))) < 8.0
    fitted, _ = fit_transitions(
        ll.Pendulum(), lambda env: (env.dynamics.mass, env.dynamics.length), states, actions, next_states
    )
    # Exact float64 data through the same arithmetic: measured relative errors 7.8e-16 (mass)
    # and 2.2e-16 (length), round-off.
    assert abs(float(fitted.dynamics.mass) / mass - 1) < 1e-14
    assert abs(float(fitted.dynamics.length) / length - 1) < 1e-14
