"""Gymnasium's classic-control envs as the reference for our scenes, step by step.

As gymnax does, Gymnasium's state is written into our `EnvState` before every step and
the next state, observation, reward and terminal flag are compared with Gymnasium's,
over whole episodes driven by a policy that reaches the clips, walls and goals, mixed
with random actions. Float64 throughout: 1e-12 relative where Gymnasium computes in
float64, 1e-6 where it keeps its state in float32 (MountainCarContinuous).
"""

import diffrax
import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.env import EnvState

from conftest import relative_error


@eqx.filter_jit
def _one_step(env, y, action, key):
    state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
    transition_key, observation_key, reward_key, terminal_key = jr.split(key, 4)
    next_state, info = env.transition(state, action, key=transition_key)
    return (
        next_state.y,
        env.observation(next_state, key=observation_key),
        env.reward(state, action, next_state, key=reward_key),
        env.terminal(next_state, key=terminal_key),
        info["solver_ok"],
    )


def _compare_episode(env, gym_env, policy, *, seed, steps, rtol, key):
    """Run Gymnasium for `steps` steps (or to termination), checking our step at each one.

    Returns Gymnasium's states (before each step) and the actions, for event assertions.
    """
    gym_env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    states, actions = [], []
    for _ in range(steps):
        y = np.array(gym_env.state, dtype=np.float64)
        action = policy(y, rng)
        y1, observation, reward, terminal, ok = _one_step(env, jnp.asarray(y), jnp.asarray(action), key)
        gym_observation, gym_reward, gym_terminated, gym_truncated, _ = gym_env.step(action)
        gym_y1 = np.array(gym_env.state, dtype=np.float64)
        assert bool(ok)
        assert relative_error(y1, gym_y1) <= rtol, (y, action, np.asarray(y1), gym_y1)
        assert relative_error(observation, gym_observation) <= max(rtol, 1e-6)
        np.testing.assert_allclose(float(reward), gym_reward, rtol=rtol, atol=rtol)
        assert bool(terminal) == gym_terminated
        assert not gym_truncated
        states.append(y)
        actions.append(action)
        if gym_terminated:
            break
    return np.array(states + [gym_y1]), actions


# ---------------------------------------------------------------------------- Pendulum


def _pendulum_policy(y, rng):
    # Pump energy (torque along the velocity) so that the speed reaches its clip; one
    # action in three at random. Actions are float32 as Gymnasium's space samples them,
    # passed as float64 so that Gymnasium's `3 / (m l^2) * u` is computed in float64 too.
    if rng.random() < 1 / 3:
        torque = rng.uniform(-2.5, 2.5)  # beyond max_torque on purpose: the action clip
    else:
        torque = 2.0 * np.sign(y[1] if y[1] != 0 else 1.0)
    return np.array([np.float32(torque)], dtype=np.float64)


def test_pendulum_matches_gymnasium(getkey):
    env = ll.Pendulum()
    gym_env = gymnasium.make("Pendulum-v1").unwrapped
    speed_clips = 0
    for seed in range(3):
        states, actions = _compare_episode(
            env, gym_env, _pendulum_policy, seed=seed, steps=200, rtol=1e-12, key=getkey()
        )
        speed_clips += int(np.sum(np.abs(states[1:, 1]) == 8.0))
    # The episodes hit the speed limit: the clip inside the step was exercised.
    assert speed_clips >= 10


def test_pendulum_energy_conserved_without_torque_under_tsit5():
    env = ll.Pendulum(
        solver="tsit5", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
        max_speed=jnp.inf,
    )
    y0 = jnp.array([2.5, 0.5])
    ys, infos = ll.rollout(env, EnvState(y=y0, steps=jnp.zeros((), dtype=int)), jnp.zeros((100, 1)), key=jr.key(0))
    assert bool(jnp.all(infos["solver_ok"]))
    energies = jax.vmap(env.dynamics.energy)(ys)
    assert relative_error(energies, jnp.full_like(energies, env.dynamics.energy(y0))) < 1e-9
    # and the motion is a real swing, not a rest
    assert float(jnp.max(jnp.abs(ys[:, 0]))) > 3.0
