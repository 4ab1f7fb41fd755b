"""`lerax_like.gymnax`: gymnax's `Environment` interface over the scenes, checked against the
functional env, against gymnax's own CartPole, and in rejax's PPO."""

import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from conftest import XLA_DEFAULTS, hybrid

import lerax_like as ll


gymnax = pytest.importorskip("gymnax")  # in the test extra: a skip here is a broken setup
import lerax_like.gymnax as lerax_gymnax  # noqa: E402


# gymnax 0.0.x steps return five values, 1.x six (terminated and truncated apart).
SIX_VALUES = hasattr(gymnax.environments.environment.Environment, "is_truncated")


def _done(outputs):
    return outputs[3] | outputs[4] if SIX_VALUES else outputs[3]


def _action(env, params, key):
    return env.action_space(params).sample(key)


# A hybrid scene's cases ("BouncingBall-v0" is BouncingBall's) are CI's, not the quick loop's.
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(name, marks=[pytest.mark.slow] if hybrid(name.rsplit("-v", 1)[0]) else [], id=name)
        for name in lerax_gymnax.registered_envs()
    ],
)
def test_observations_are_the_functional_envs(name, getkey):
    """Same scene, same keys: `reset` and `step_env` give the functional env's states,
    observations, rewards and terminations exactly."""
    env, params = lerax_gymnax.make(name)
    scene = type(env.scene(params))()  # built afresh with its defaults, as `make` builds it
    reset_key, action_key, step_key = jr.split(getkey(), 3)
    observation, state = env.reset(reset_key, params)
    # gymnax's `reset` is jitted: so is the reference, for the same rounding.
    scene_state, scene_observation, _ = eqx.filter_jit(scene.reset)(key=reset_key)
    np.testing.assert_array_equal(observation, scene_observation)
    np.testing.assert_array_equal(state.y, scene_state.y)
    action = _action(env, params, action_key)
    observation, next_state, reward, done, info = env.step_env(step_key, state, action, params)
    scene_next, scene_observation, scene_reward, terminated, _ = scene.advance(state, action, key=step_key)
    np.testing.assert_array_equal(observation, scene_observation)
    np.testing.assert_array_equal(next_state.y, scene_next.y)
    assert float(reward) == float(scene_reward) and bool(info["terminated"]) == bool(terminated)
    assert isinstance(env, gymnax.environments.environment.Environment)


def test_cartpole_euler_steps_as_gymnax_cartpole(getkey):
    """gymnax's own CartPole-v1 as the independent reference: from gymnax's start states,
    every action, our Euler step lands on gymnax's next state (float64)."""
    reference, reference_params = gymnax.make("CartPole-v1")
    env, params = lerax_gymnax.make("CartPole-v1", solver="euler")
    for key in jr.split(getkey(), 20):
        reset_key, step_key = jr.split(key)
        with jax.numpy_dtype_promotion("standard"):
            _, reference_state = reference.reset(reset_key, reference_params)
        y = jnp.stack([reference_state.x, reference_state.x_dot, reference_state.theta, reference_state.theta_dot])
        state = ll.EnvState(y=y, steps=jnp.zeros((), int))
        for action in (0, 1):
            # gymnax mixes Python floats and booleans, which strict promotion (conftest) refuses.
            with jax.numpy_dtype_promotion("standard"):
                expected, _, _, _, _ = reference.step_env(step_key, reference_state, action, reference_params)
            observation, _, reward, _, _ = env.step_env(step_key, state, jnp.asarray(action), params)
            np.testing.assert_allclose(observation, expected, rtol=1e-12, atol=1e-15)
            assert float(reward) == 1.0


def test_autoreset_and_episode_limit_as_data(getkey):
    """gymnax's `step`: the episode ends at `max_steps_in_episode` (data: no recompilation),
    and the returned observation is then a fresh start's."""
    env, params = lerax_gymnax.make("CartPoleContinuous", theta_threshold_radians=jnp.inf, x_threshold=jnp.inf)
    step = jax.jit(env.step)
    for limit in (3, 5):
        limited = params.replace(max_steps_in_episode=jnp.asarray(limit))
        key = getkey()
        observation, state = env.reset(key, limited)
        for index in range(limit):
            outputs = step(jr.fold_in(key, index), state, jnp.zeros(1), limited)
            observation, state = outputs[0], outputs[1]
            assert bool(_done(outputs)) == (index == limit - 1)
        assert int(state.steps) == 0  # reset
        # The observation of a fresh start: within CartPole's start bounds.
        assert np.all(np.abs(np.asarray(observation)) <= 0.05)
    assert step._cache_size() == 1


def test_vmap_over_physical_parameters(getkey):
    """A batch of pole masses in `params`, as gymnax's users batch params: each env steps as
    the scene built with its mass."""
    env, params = lerax_gymnax.make("CartPole-v1", solver="rk4")
    masses = jnp.asarray([0.05, 0.1, 0.5])
    batched = eqx.tree_at(lambda p: p.scene.dynamics.pole_mass, params, masses)
    in_axes = jax.tree.map(lambda _: None, params)
    in_axes = eqx.tree_at(lambda p: p.scene.dynamics.pole_mass, in_axes, 0, is_leaf=lambda x: x is None)
    key = getkey()
    _, state = env.reset(key, params)
    observations = jax.vmap(env.step_env, in_axes=(None, None, None, in_axes))(key, state, jnp.asarray(1), batched)[0]
    for mass, observation in zip(masses, observations):
        scene = ll.make("CartPole", solver="rk4", pole_mass=mass)
        np.testing.assert_array_equal(observation, scene.advance(state, jnp.asarray(1), key=key)[1])
    assert not np.allclose(observations[0], observations[2])


@pytest.mark.parametrize("name", ["CartPole-v1", "Pendulum-v1", "Acrobot-v1", "MountainCarContinuous-v0", "NLinkPendulum"])
def test_spaces_are_gymnax_spaces(name):
    env, params = lerax_gymnax.make(name)
    scene = env.scene(params)
    action_space, observation_space = env.action_space(params), env.observation_space(params)
    assert isinstance(observation_space, gymnax.environments.spaces.Box)
    np.testing.assert_array_equal(observation_space.low, scene.observation_space.low)
    np.testing.assert_array_equal(observation_space.high, scene.observation_space.high)
    if isinstance(scene.action_space, ll.Discrete):
        assert isinstance(action_space, gymnax.environments.spaces.Discrete)
        assert action_space.n == scene.action_space.n == env.num_actions
    else:
        assert isinstance(action_space, gymnax.environments.spaces.Box)
        assert action_space.shape == scene.action_space.shape and env.num_actions == action_space.shape[0]
    assert env.name == name and hash(env) == hash(env)


def test_gradient_through_a_step_to_a_parameter(getkey):
    """Nothing is cut from the gradient (gymnax's own envs stop it): d(observation)/d(force_mag)
    by JAX against a central difference."""
    env, params = lerax_gymnax.make("CartPoleContinuous", solver="rk4")
    _, state = env.reset(getkey(), params)

    def velocity(force_mag):
        moved = eqx.tree_at(lambda p: p.scene.force_mag, params, force_mag)
        return env.step_env(None, state, jnp.ones(1), moved)[0][1]

    h = 1e-5
    difference = (velocity(10.0 + h) - velocity(10.0 - h)) / (2 * h)
    np.testing.assert_allclose(jax.grad(velocity)(10.0), difference, rtol=1e-7)


def test_unknown_name_and_missing_gymnax(monkeypatch):
    with pytest.raises(ValueError, match="unknown env 'CartPole-v9'.*CartPole-v1"):
        lerax_gymnax.make("CartPole-v9")
    from lerax_like.gymnax import _make

    _make.environment_class.cache_clear()
    monkeypatch.setitem(sys.modules, "gymnax", None)
    try:
        with pytest.raises(ImportError, match=r"pip install 'lerax_like\[gymnax\]'"):
            lerax_gymnax.make("CartPole-v1")
    finally:
        _make.environment_class.cache_clear()


@pytest.mark.slow
def test_rejax_ppo_trains_cartpole_as_on_gymnax():
    """rejax's PPO with its CartPole config, 8 seeds vmapped, on gymnax's CartPole and on ours
    (Euler, float32 as rejax runs): ours reaches at least 0.8x gymnax's mean final return.

    `eval_freq` is the run's length, so that rejax evaluates once, at the end (128 episodes):
    evaluations draw from the train state's key without changing it, so this changes only
    the time taken, not what is learnt. Compiled with XLA's defaults, a training took 13 s
    (7 s compiling, 6 s running) on the idle 2-core machine, against 21 s (3 s and 18 s) with
    the suite's flags.
    """
    pytest.importorskip("rejax")
    from benchmarks._workload import REJAX_CARTPOLE_PPO, cartpole_env, rejax_ppo_training

    if SIX_VALUES:
        pytest.fail("rejax 0.1.x needs gymnax 0.0.x (five-value steps); install gymnax==0.0.9")
    final = {}
    with jax.enable_x64(False), jax.numpy_dtype_promotion("standard"):
        for solver in (None, "euler"):
            env, params = cartpole_env(solver)
            train, keys = rejax_ppo_training(env, params, 8, eval_freq=REJAX_CARTPOLE_PPO["total_timesteps"])
            # Training is what takes the time here, not compiling: the program is compiled with
            # XLA's defaults, as a user's is (the suite's flags cut compiling and slow running).
            _, (_, returns) = train.lower(keys).compile(XLA_DEFAULTS)(keys)
            final[solver] = float(np.asarray(returns)[:, -1, :].mean())
    assert final["euler"] >= 0.8 * final[None], final
