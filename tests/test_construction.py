"""Bad input is refused at construction with a message naming the parameter and its range."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.env import EnvState


@pytest.mark.parametrize("name", ["cart_mass", "pole_mass", "half_length", "dt", "force_mag", "gravity"])
@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_non_positive_or_nan_parameters_are_refused(name, value):
    for scene in (ll.CartPole, ll.CartPoleContinuous):
        with pytest.raises(ValueError, match=rf"{name} must be .*\(0, inf\)"):
            scene(**{name: value})


@pytest.mark.parametrize("name", ["theta_threshold_radians", "x_threshold"])
def test_thresholds_may_be_infinite_but_not_negative_or_nan(name):
    ll.CartPole(**{name: jnp.inf})
    for value in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match=name):
            ll.CartPole(**{name: value})


@pytest.mark.parametrize("solver", ["euler", "rk4", diffrax.Euler(), ll.RK4()])
def test_solver_without_error_estimate_refuses_adaptive_controller(solver):
    with pytest.raises(ValueError, match="no error estimate"):
        ll.CartPole(solver=solver, stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-8))


def test_unknown_solver_name_lists_the_presets():
    with pytest.raises(ValueError, match="euler"):
        ll.CartPole(solver="rk5")
    with pytest.raises(TypeError, match="diffrax solver"):
        ll.Integrator("euler")


def test_every_preset_and_solver_object_builds_and_steps():
    state = EnvState(y=jnp.array([0.0, 0.0, 0.1, 0.0]), steps=jnp.zeros((), int))
    transition = eqx.filter_jit(lambda env: env.transition(state, jnp.asarray(1), key=jax.random.key(0)))
    tight = ll.make_integrator("dopri8", diffrax.PIDController(rtol=1e-12, atol=1e-12))
    reference, _ = transition(ll.CartPole(solver=tight))
    for solver in (*ll.SOLVER_PRESETS, diffrax.Bosh3(), ll.make_integrator("rk4", substeps=4)):
        next_state, info = transition(ll.CartPole(solver=solver))
        assert bool(info["solver_ok"]) and int(info["solver_steps"]) >= 1
        # One step of dt = 0.02: every method is within Euler's local error of the exact
        # flow, dt^2 / 2 * |y''| with |y''| about 13 rad/s^2 here, so under 3e-3.
        np.testing.assert_allclose(np.asarray(next_state.y), np.asarray(reference.y), atol=3e-3)


def test_construction_under_filter_vmap_with_traced_parameters():
    masses = jnp.linspace(0.05, 2.0, 8)
    envs = eqx.filter_vmap(lambda m: ll.CartPole(pole_mass=m))(masses)
    np.testing.assert_array_equal(np.asarray(envs.dynamics.pole_mass), np.asarray(masses))


def test_spaces_sample_what_they_contain(getkey):
    env = ll.CartPole()
    assert bool(env.action_space.contains(env.action_space.sample(key=getkey())))
    assert not bool(env.action_space.contains(2))
    continuous = ll.CartPoleContinuous()
    action = continuous.action_space.sample(key=getkey())
    assert action.shape == (1,) and bool(continuous.action_space.contains(action))
    assert not bool(continuous.action_space.contains(jnp.array([1.5])))
    state, observation, _ = env.reset(key=getkey())
    assert bool(env.observation_space.contains(observation))
    # Unbounded coordinates sample finite values.
    assert np.all(np.isfinite(np.asarray(env.observation_space.sample(key=getkey()))))
