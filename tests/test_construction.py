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
            ll.make(scene, **{name: value})


@pytest.mark.parametrize("name", ["theta_threshold_radians", "x_threshold"])
def test_thresholds_may_be_infinite_but_not_negative_or_nan(name):
    ll.make("CartPole", **{name: jnp.inf})
    for value in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match=name):
            ll.make("CartPole", **{name: value})


@pytest.mark.parametrize("solver", ["euler", "rk4", diffrax.Euler(), ll.RK4()])
def test_solver_without_error_estimate_refuses_adaptive_controller(solver):
    with pytest.raises(ValueError, match="no error estimate"):
        ll.make("CartPole", solver=solver, stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-8))


def test_unknown_solver_name_lists_the_presets():
    with pytest.raises(ValueError, match="euler"):
        ll.make("CartPole", solver="rk5")
    with pytest.raises(TypeError, match="diffrax solver"):
        ll.Integrator("euler")


@pytest.mark.slow  # one compiled transition per solver: 319 s at load 12 on 2 cores
def test_every_preset_and_solver_object_builds_and_steps():
    state = EnvState(y=jnp.array([0.0, 0.0, 0.1, 0.0]), steps=jnp.zeros((), int))
    transition = eqx.filter_jit(lambda env: env.transition(state, jnp.asarray(1), key=jax.random.key(0)))
    tight = ll.make_integrator("dopri8", diffrax.PIDController(rtol=1e-12, atol=1e-12))
    reference, _ = transition(ll.make("CartPole", solver=tight))
    # One step of dt = 0.02 from the same state; the reference agrees with SciPy's DOP853 at
    # 1e-13 to 4e-16. Errors measured (max-norm): Euler and semi-implicit Euler 2.6e-3 (Euler's
    # local error dt^2 / 2 * |y''|, |y''| about 13 rad/s^2), Heun, midpoint, Ralston 3.0e-4,
    # implicit Euler (adaptive, rtol 1e-3) 9.4e-5, Bosh3 1.5e-6, RK4 1.5e-7, RK4 with 4
    # substeps 6.0e-10, Kvaerno3 9.9e-10, Kvaerno4 4.3e-9, Tsit5, Dopri5, Kvaerno5 below
    # 2.1e-12. Each bound is about three times its error (the first-order ones keep the
    # earlier 3e-3), so a method that lost its order fails.
    bounds = {
        "euler": 3e-3, "semi_implicit_euler": 3e-3, "heun": 1e-3, "midpoint": 1e-3, "ralston": 1e-3,
        "implicit_euler": 3e-4, "rk4": 5e-7, "kvaerno3": 3e-9, "kvaerno4": 1.5e-8,
        "tsit5": 1e-11, "dopri5": 1e-11, "dopri8": 1e-11, "kvaerno5": 1e-11,
    }
    solvers = {**{name: name for name in ll.SOLVERS.names}, "Bosh3": diffrax.Bosh3(),
               "rk4, 4 substeps": ll.make_integrator("rk4", substeps=4)}
    bounds.update({"Bosh3": 5e-6, "rk4, 4 substeps": 2e-9})
    assert set(solvers) <= set(bounds), f"no bound for {set(solvers) - set(bounds)}"
    for name, solver in solvers.items():
        next_state, info = transition(ll.make("CartPole", solver=solver))
        assert bool(info["solver_ok"]) and int(info["solver_steps"]) >= 1
        error = float(np.max(np.abs(np.asarray(next_state.y) - np.asarray(reference.y))))
        assert error < bounds[name], f"{name}: error {error:.2e} against Dopri8 at 1e-12"


def test_construction_under_filter_vmap_with_traced_parameters():
    masses = jnp.linspace(0.05, 2.0, 8)
    envs = eqx.filter_vmap(lambda m: ll.make("CartPole", pole_mass=m))(masses)
    np.testing.assert_array_equal(np.asarray(envs.dynamics.pole_mass), np.asarray(masses))


@pytest.mark.slow  # 2.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
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
