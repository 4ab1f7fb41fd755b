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


def _compare_episode(env, gym_env, policy, *, seed, steps, rtol, key, start=None):
    """Run Gymnasium for `steps` steps (or to termination), checking our step at each one.

    `start`, if given, is written into Gymnasium's state after its reset (to reach
    states, such as high speeds, that its own start never does). Returns Gymnasium's
    states (before each step and after the last), the actions and the rewards.
    """
    gym_env.reset(seed=seed)
    if start is not None:
        gym_env.state = np.array(start, dtype=np.float64)
    rng = np.random.default_rng(seed)
    states, actions, rewards = [], [], []
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
        rewards.append(gym_reward)
        if gym_terminated:
            break
    return np.array(states + [gym_y1]), actions, np.array(rewards)


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
        states, _, _ = _compare_episode(
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


# ----------------------------------------------------------------------------- Acrobot


def _acrobot_policy(y, rng):
    # Torque along the first link's velocity pumps energy in; one action in four at random.
    if rng.random() < 0.25:
        return int(rng.integers(3))
    return 2 if y[2] > 0 else 0


def test_acrobot_matches_gymnasium(getkey):
    env = ll.Acrobot()
    gym_env = gymnasium.make("Acrobot-v1").unwrapped
    wraps = velocity_clips = terminations = 0
    # Two episodes from Gymnasium's start, and one thrown from a fast state so that the
    # speed limits (4 pi, 9 pi) bite.
    for seed, start in [(0, None), (1, None), (2, [-0.09, 2.97, -4.6, -17.8])]:
        states, _, rewards = _compare_episode(
            env, gym_env, _acrobot_policy, seed=seed, steps=500, rtol=1e-12, key=getkey(), start=start
        )
        wraps += int(np.sum(np.abs(np.diff(states[:, :2], axis=0)) > np.pi))
        velocity_clips += int(np.sum(np.abs(states[1:, 2]) == 4 * np.pi) + np.sum(np.abs(states[1:, 3]) == 9 * np.pi))
        terminations += int(np.sum(rewards == 0.0))
    assert wraps >= 3 and velocity_clips >= 1 and terminations >= 1, (wraps, velocity_clips, terminations)


def test_acrobot_vector_field_is_gymnasiums_dsdt():
    dynamics = ll.AcrobotDynamics()
    gym_env = gymnasium.make("Acrobot-v1").unwrapped
    rng = np.random.default_rng(0)
    for _ in range(20):
        y = rng.uniform([-np.pi, -np.pi, -4 * np.pi, -9 * np.pi], [np.pi, np.pi, 4 * np.pi, 9 * np.pi])
        torque = rng.choice([-1.0, 0.0, 1.0])
        expected = np.array(gym_env._dsdt(np.append(y, torque))[:4])
        ours = dynamics.vector_field(0.0, jnp.asarray(y), jnp.array([torque]))
        assert relative_error(ours, expected) < 1e-13


def test_acrobot_book_equations_conserve_energy_and_nips_do_not():
    # Independent check of the "book" vector field: with no torque, the rate of change of
    # the double pendulum's energy along the field, grad(E) . f, vanishes at every state.
    # The NeurIPS paper's equations lack a Coriolis term and do not conserve it.
    rng = np.random.default_rng(1)
    states = jnp.asarray(rng.uniform([-np.pi, -np.pi, -5, -5], [np.pi, np.pi, 5, 5], size=(50, 4)))
    no_torque = jnp.zeros((1,))
    for equations, conserved in [("book", True), ("nips", False)]:
        dynamics = ll.AcrobotDynamics(equations=equations)
        power = jax.vmap(lambda y: jnp.dot(jax.grad(dynamics.energy)(y), dynamics.vector_field(0.0, y, no_torque)))
        energy_scale = jnp.max(jnp.abs(jax.vmap(dynamics.energy)(states)))
        worst = float(jnp.max(jnp.abs(power(states))) / energy_scale)
        assert (worst < 1e-13) if conserved else (worst > 1e-2), (equations, worst)


# ------------------------------------------------------------------------- MountainCar


def _mountain_car_policy(y, rng):
    # Accelerate along the velocity (the classic energy-pumping policy), one action in
    # five at random; push left at the start to drive into the left wall.
    if rng.random() < 0.2:
        return int(rng.integers(3))
    return 2 if y[1] > 0 else 0


def test_mountain_car_matches_gymnasium(getkey):
    env = ll.MountainCar()
    gym_env = gymnasium.make("MountainCar-v0").unwrapped
    walls = speed_clips = goals = 0
    # From Gymnasium's start, and from a fast state heading for the left wall.
    for seed, start in [(0, None), (1, None), (2, [-1.0, -0.069]), (3, [-0.9, 0.069])]:
        states, _, _ = _compare_episode(
            env, gym_env, _mountain_car_policy, seed=seed, steps=200, rtol=1e-12, key=getkey(), start=start
        )
        walls += int(np.sum((states[1:, 0] == -1.2) & (states[1:, 1] == 0.0)))
        speed_clips += int(np.sum(np.abs(states[1:, 1]) == 0.07))
        goals += int(states[-1, 0] >= 0.5)
    assert walls >= 1 and speed_clips >= 1 and goals >= 2, (walls, speed_clips, goals)


def _continuous_mountain_car_policy(y, rng):
    # Full throttle along the velocity, and one action in three at random, beyond the
    # action bounds on purpose (the action clip, and the penalty on the unclipped action).
    if rng.random() < 1 / 3:
        throttle = rng.uniform(-1.5, 1.5)
    else:
        throttle = 1.0 if y[1] >= 0 else -1.0
    return np.array([np.float32(throttle)], dtype=np.float64)


def test_mountain_car_continuous_matches_gymnasium(getkey):
    # Gymnasium keeps this env's state in float32: hence 1e-6.
    env = ll.MountainCarContinuous()
    gym_env = gymnasium.make("MountainCarContinuous-v0").unwrapped
    walls = speed_clips = goals = 0
    for seed, start in [(0, None), (1, None), (2, [-1.0, -0.069]), (3, [-0.9, 0.069])]:
        states, _, rewards = _compare_episode(
            env, gym_env, _continuous_mountain_car_policy, seed=seed, steps=999, rtol=1e-6, key=getkey(),
            start=start,
        )
        walls += int(np.sum((states[1:, 0] == np.float32(-1.2)) & (states[1:, 1] == 0.0)))
        speed_clips += int(np.sum(np.abs(states[1:, 1]) == np.float32(0.07)))
        goals += int(np.sum(rewards > 90.0))
    assert walls >= 1 and speed_clips >= 1 and goals >= 2, (walls, speed_clips, goals)
