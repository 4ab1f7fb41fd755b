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
def _steps_from(env, ys, actions, key):
    """Our transition, observation, reward and terminal flag from each state of `ys`."""

    def one_step(y, action, key):
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

    return jax.vmap(one_step)(ys, actions, jr.split(key, ys.shape[0]))


def _compare_episode(env, gym_env, policy, *, seed, steps, rtol, key, start=None):
    """Run Gymnasium for `steps` steps (or to termination); our step from each of its states.

    `start`, if given, is written into Gymnasium's state after its reset (to reach
    states, such as high speeds, that its own start never does). Every step is checked
    from Gymnasium's state before it, so the steps are independent and are evaluated in
    one batch. Returns Gymnasium's states (before each step and after the last), the
    actions and the rewards.
    """
    gym_env.reset(seed=seed)
    if start is not None:
        gym_env.state = np.array(start, dtype=np.float64)
    rng = np.random.default_rng(seed)
    states, actions, next_states, observations, rewards, terminations = [], [], [], [], [], []
    for _ in range(steps):
        y = np.array(gym_env.state, dtype=np.float64)
        action = policy(y, rng)
        gym_observation, gym_reward, gym_terminated, gym_truncated, _ = gym_env.step(action)
        assert not gym_truncated
        states.append(y)
        actions.append(action)
        next_states.append(np.array(gym_env.state, dtype=np.float64))
        observations.append(gym_observation)
        rewards.append(gym_reward)
        terminations.append(gym_terminated)
        if gym_terminated:
            break
    # Padded to `steps` rows (repeats of the first step), so that every episode of a test
    # reuses one compilation.
    n = len(states)
    padded_states = np.array(states + states[:1] * (steps - n))
    padded_actions = np.array(actions + actions[:1] * (steps - n))
    ys1, ours_observations, ours_rewards, ours_terminations, ok = jax.tree.map(
        lambda x: np.asarray(x)[:n], _steps_from(env, jnp.asarray(padded_states), jnp.asarray(padded_actions), key)
    )
    assert np.all(ok)
    for k in range(len(states)):
        assert relative_error(ys1[k], next_states[k]) <= rtol, (k, states[k], actions[k], ys1[k], next_states[k])
        assert relative_error(ours_observations[k], observations[k]) <= max(rtol, 1e-6), k
    np.testing.assert_allclose(ours_rewards, np.array(rewards), rtol=rtol, atol=rtol)
    np.testing.assert_array_equal(ours_terminations, np.array(terminations))
    return np.array(states + [next_states[-1]]), actions, np.array(rewards)


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
    env = ll.make("Pendulum",
        solver="tsit5", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
        max_speed=jnp.inf,
    )
    y0 = jnp.array([2.5, 0.5])
    ys, infos = ll.rollout(env, EnvState(y=y0, steps=jnp.zeros((), dtype=int)), jnp.zeros((40, 1)), key=jr.key(0))
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
        power = jax.jit(jax.vmap(lambda y: jnp.dot(jax.grad(dynamics.energy)(y), dynamics.vector_field(0.0, y, no_torque))))
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


# ------------------------------------------------------------------ CartPole, unchanged


def _cartpole_policy(y, rng):
    if rng.random() < 0.2:
        return int(rng.integers(2))
    x, x_dot, theta, theta_dot = y
    return int(theta + 0.5 * theta_dot + 0.05 * x + 0.1 * x_dot > 0)


def test_cartpole_still_matches_gymnasium(getkey):
    # `transition` now hands the scene's projection (identity here) to the integrator.
    states, _, _ = _compare_episode(
        ll.CartPole(), gymnasium.make("CartPole-v1").unwrapped, _cartpole_policy, seed=0, steps=500,
        rtol=1e-12, key=getkey(),
    )
    assert len(states) > 50


# ------------------------------------------------------------- any solver, every scene


_SCENES = [ll.Pendulum, ll.Acrobot, ll.MountainCar, ll.MountainCarContinuous]


@pytest.mark.slow  # about 8 s per scene on 2 cores
@pytest.mark.parametrize("scene", _SCENES, ids=lambda scene: scene.__name__)
def test_scene_runs_with_rk4_and_tsit5(scene, getkey):
    # Every scene takes any solver. With the projection applied after the step, RK4 and
    # Tsit5 integrate the same vector field: against Tsit5 at a tight tolerance, Tsit5 is
    # within its own tolerance, and RK4's error falls as the fourth order predicts when
    # its step is halved (Acrobot's 0.2 s step is large: it need not be small).
    def rollout(integrator):
        env = scene(integrator=integrator)
        state, _, _ = env.reset(key=jr.key(3))
        actions = jax.vmap(lambda key: env.action_space.sample(key=key))(jr.split(jr.key(4), 5))
        ys, infos = eqx.filter_jit(ll.rollout)(env, state, actions, key=getkey())
        assert bool(jnp.all(infos["solver_ok"])) and bool(jnp.all(jnp.isfinite(ys)))
        return ys

    reference = rollout(ll.make_integrator("tsit5", diffrax.PIDController(rtol=1e-11, atol=1e-13)))
    assert relative_error(rollout(ll.make_integrator("tsit5")), reference) < 1e-5
    rk4_error = relative_error(rollout(ll.make_integrator("rk4")), reference)
    halved_error = relative_error(rollout(ll.make_integrator("rk4", substeps=2)), reference)
    assert rk4_error < 1e-2 and halved_error < rk4_error / 8


# ------------------------------------------------------------------ SemiImplicitEuler


def test_semi_implicit_euler_is_first_order():
    # No clip, no torque: the local error of one step, against Tsit5 at tight tolerance,
    # falls as h**2 (a first-order method). One compilation, the step sizes batched.
    dynamics = ll.PendulumDynamics()
    y0, u = jnp.array([2.0, 0.5]), jnp.zeros((1,))
    steps = jnp.array([0.04, 0.02, 0.01, 0.005])

    def errors(h):
        reference, _ = ll.make_integrator(
            "tsit5", diffrax.PIDController(rtol=1e-13, atol=1e-13)
        ).integrate(dynamics.vector_field, y0, u, h)
        y1, info = ll.make_integrator("semi_implicit_euler").integrate(
            dynamics.vector_field, y0, u, h, velocity_indices=dynamics.velocity_indices
        )
        return jnp.max(jnp.abs(y1 - reference)), info["solver_ok"]

    local_errors, ok = jax.jit(jax.vmap(errors))(steps)
    assert bool(jnp.all(ok))
    slope = np.polyfit(np.log(steps), np.log(np.asarray(local_errors)), 1)[0]
    assert 1.9 < slope < 2.1, (slope, local_errors)


def test_semi_implicit_euler_keeps_energy_bounded_where_euler_drifts():
    # Symplectic: over 2000 steps of the frictionless pendulum the energy error of
    # semi-implicit Euler stays O(dt) and does not grow; explicit Euler's grows steadily.
    state = EnvState(y=jnp.array([2.0, 0.0]), steps=jnp.zeros((), dtype=int))
    drift = {}
    for solver in ["semi_implicit_euler", "euler"]:
        env = ll.make("Pendulum", solver=solver, max_speed=jnp.inf, max_episode_steps=None)
        ys, _ = eqx.filter_jit(ll.rollout)(env, state, jnp.zeros((2000, 1)), key=jr.key(0))
        error = jnp.abs(jax.vmap(env.dynamics.energy)(ys) - env.dynamics.energy(state.y))
        drift[solver] = (float(jnp.max(error[:200])), float(jnp.max(error[-200:])))
    early, late = drift["semi_implicit_euler"]
    assert late < 2 * early and late < 0.5, drift
    early, late = drift["euler"]
    assert late > 5 * early, drift


def test_semi_implicit_euler_refuses_what_it_cannot_do():
    with pytest.raises(ValueError, match="no error estimate"):
        ll.make_integrator("semi_implicit_euler", diffrax.PIDController(rtol=1e-6, atol=1e-6))
    assert not ll.has_error_estimate(ll.SemiImplicitEuler())
    # Without velocity_indices it cannot tell positions from velocities.
    with pytest.raises(ValueError, match="velocity_indices"):
        ll.make_integrator("semi_implicit_euler").integrate(
            lambda t, y, u: -y, jnp.ones(2), jnp.zeros(1), 0.1
        )


def test_cartpole_runs_with_semi_implicit_euler(getkey):
    # The solver is general: any dynamics that declares its velocities can use it.
    env = ll.make("CartPole", solver="semi_implicit_euler")
    state, _, _ = env.reset(key=getkey())
    ys, infos = eqx.filter_jit(ll.rollout)(env, state, jnp.ones((20,), dtype=int), key=getkey())
    euler = ll.CartPole()
    ys_euler, _ = eqx.filter_jit(ll.rollout)(euler, state, jnp.ones((20,), dtype=int), key=getkey())
    assert bool(jnp.all(infos["solver_ok"]))
    # Both first order in dt = 0.02: close, not equal.
    assert 0 < relative_error(ys, ys_euler) < 0.05


# ------------------------------------------------------------------------- construction


@pytest.mark.parametrize(
    "make, parameter",
    [
        (lambda: ll.Pendulum(max_torque=-1.0), "max_torque"),
        (lambda: ll.Pendulum(max_speed=0.0), "max_speed"),
        (lambda: ll.Pendulum(dt=0.0), "dt"),
        (lambda: ll.make("Pendulum", length=float("nan")), "length"),
        (lambda: ll.make("Pendulum", gravity=-10.0), "gravity"),
        (lambda: ll.make("Acrobot", link_mass_1=0.0), "link_mass_1"),
        (lambda: ll.make("Acrobot", link_moment_of_inertia_2=-1.0), "link_moment_of_inertia_2"),
        (lambda: ll.Acrobot(max_velocity_2=-1.0), "max_velocity_2"),
        (lambda: ll.Acrobot(torque=0.0), "torque"),
        (lambda: ll.make("Acrobot", equations="paper"), "equations"),
        (lambda: ll.MountainCar(force=0.0), "force"),
        (lambda: ll.MountainCar(min_position=1.0), "min_position"),
        (lambda: ll.make("MountainCar", gravity=float("inf")), "gravity"),
        (lambda: ll.MountainCarContinuous(power=-0.1), "power"),
        (lambda: ll.MountainCarContinuous(goal_velocity=float("nan")), "goal_velocity"),
        (lambda: ll.MountainCarContinuous(max_speed=-0.07), "max_speed"),
    ],
)
def test_bad_parameters_refused_by_name(make, parameter):
    with pytest.raises(ValueError, match=parameter):
        make()


def test_parameters_may_be_traced():
    # Built under vmap (a batch of gravities): the checks let tracers through.
    envs = eqx.filter_vmap(lambda g: ll.make("Pendulum", gravity=g))(jnp.array([9.0, 10.0, 11.0]))
    assert envs.dynamics.gravity.shape == (3,)


@pytest.mark.slow  # 3.3 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_gradient_through_projected_semi_implicit_steps():
    # The scenes stay differentiable: d(loss)/d(gravity) through 30 Pendulum steps, in
    # which the speed clip binds at some steps, against central finite differences.
    env = ll.Pendulum(max_speed=6.0)
    state = EnvState(y=jnp.array([0.3, 3.0]), steps=jnp.zeros((), dtype=int))
    torques = jnp.full((30, 1), 2.0)

    @jax.jit
    def loss(gravity):
        ys, _ = ll.rollout(eqx.tree_at(lambda e: e.dynamics.gravity, env, gravity), state, torques, key=jr.key(0))
        return jnp.sum(jnp.cos(ys[:, 0])), jnp.sum(jnp.abs(ys[:, 1]) == 6.0)

    gravity, h = jnp.asarray(10.0), 1e-6
    gradient = jax.grad(lambda g: loss(g)[0])(gravity)
    finite_difference = (loss(gravity + h)[0] - loss(gravity - h)[0]) / (2 * h)
    assert int(loss(gravity)[1]) >= 1  # the clip binds
    assert relative_error(gradient, finite_difference) < 1e-6
