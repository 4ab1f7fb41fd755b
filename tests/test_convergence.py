"""Convergence of the env step against SciPy's DOP853 at rtol = atol = 1e-13.

Orders are fitted by regression of log error on log dt, over errors between the
reference floor and 1e-2.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import lerax_like as ll
from lerax_like.env import EnvState


HORIZON = 1.0
Y0 = np.array([0.1, -0.2, 0.5, 0.3])
ACTION = 0.3


def _env(dt, solver, stepsize_controller=None):
    return ll.make("CartPoleContinuous",
        dt=dt,
        solver=solver,
        stepsize_controller=stepsize_controller,
        theta_threshold_radians=jnp.inf,
        x_threshold=jnp.inf,
    )


@pytest.fixture(scope="module")
def reference():
    env = _env(0.1, "euler")
    vector_field = jax.jit(lambda y: env.dynamics.vector_field(0.0, y, env.physical_input(jnp.array([ACTION]))))
    solution = solve_ivp(
        lambda t, y: np.asarray(vector_field(jnp.asarray(y))), (0.0, HORIZON), Y0, method="DOP853", rtol=1e-13, atol=1e-13
    )
    assert solution.success
    return solution.y[:, -1]


@eqx.filter_jit
def _final_state(env, steps):
    # A loop with a traced trip count: one compilation serves every dt of a solver.
    def body(_, carry):
        state, ok = carry
        state, info = env.transition(state, jnp.array([ACTION]), key=jax.random.key(0))
        return state, ok & info["solver_ok"]

    state = EnvState(y=jnp.asarray(Y0), steps=jnp.zeros((), int))
    state, ok = jax.lax.fori_loop(0, steps, body, (state, jnp.asarray(True)))
    return state.y, ok


def _fitted_order(solver, exponents, reference, stepsize_controller=None):
    dts, errors = [], []
    for k in exponents:
        dt = 2.0**-k  # exact in binary, so steps * dt is exactly the horizon
        y, ok = _final_state(_env(dt, solver, stepsize_controller), jnp.asarray(round(HORIZON / dt)))
        assert bool(ok)
        dts.append(dt)
        errors.append(np.max(np.abs(np.asarray(y) - reference)))
    dts, errors = np.array(dts), np.array(errors)
    fit = (errors > 1e-11) & (errors < 1e-2)
    assert fit.sum() >= 3, f"too few errors in the fitting range: {errors}"
    return np.polyfit(np.log(dts[fit]), np.log(errors[fit]), 1)[0]


@pytest.mark.parametrize(
    "solver, order, exponents, controller",
    [
        ("euler", 1, range(11, 16), None),
        ("heun", 2, range(4, 9), None),
        ("midpoint", 2, range(4, 9), None),
        ("rk4", 4, range(2, 7), None),
        # Tsit5's leading error coefficients are tuned small, so its error
        # falls faster than h^5 (about h^7) until dt ~ 1/32: fit in the asymptotic range.
        ("tsit5", 5, range(5, 9), diffrax.ConstantStepSize()),
    ],
)
def test_convergence_order(solver, order, exponents, controller, reference):
    assert abs(_fitted_order(solver, exponents, reference, controller) - order) < 0.3


@pytest.mark.slow  # 6.8 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_adaptive_tsit5_is_within_1e_7(reference):
    env = _env(0.02, "tsit5", diffrax.PIDController(rtol=1e-9, atol=1e-12))
    y, ok = _final_state(env, jnp.asarray(50))
    assert bool(ok)
    assert np.max(np.abs(np.asarray(y) - reference)) < 1e-7
