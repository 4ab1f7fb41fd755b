"""A friction condition that dips below zero and back within one adaptive step is found, not skipped.

The friction cart-pole (mu_s = 0.3, mu_k = 0.15, no push) with its pole swinging over the top at
about 14.7 rad/s: near the top the pole's centripetal pull lifts the cart, and the normal force
`N_c` is negative for 13 to 24 ms, inside one 50 ms env step that Tsit5 at rtol 1e-3 covers in two
steps. Without the grazing guard both sign changes fell inside one solver step and neither was
located (0 switches; the state 2e-4 and 1.2e-3 off the reference at the end of the step, measured
with the guard switched off); with it, both are located and the state is within the solver's
tolerance of the SciPy event-located reference.

Also the cubic Hermite's lowest point that the guards (impacts' and friction's) rely on, against a
fine grid: its root choice was wrong for half of all dips (where the cubic's leading coefficient
is negative) before the fix.
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis.modes_reference import modes_reference_step, reference_modes
from lerax_like.hybrid import hermite_dip
from lerax_like.integrate import make_integrator
from lerax_like.stick_slip import NORMAL_FLIPS


@pytest.mark.slow  # 3.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_the_hermite_dip_is_the_lowest_point_of_the_cubic():
    rng = np.random.default_rng(0)
    g0, g1 = rng.uniform(0, 1, (2, 400))
    m0, m1 = -rng.uniform(0, 5, 400), rng.uniform(0, 5, 400)
    s = np.linspace(0, 1, 100_001)[:, None]
    cubic = ((2 * s**3 - 3 * s**2 + 1) * g0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * g1
             + (s**3 - s**2) * m1)
    at, lowest = jax.vmap(hermite_dip)(*(jnp.asarray(x) for x in (g0, g1, m0, m1)))
    leading = 6 * g0 + 3 * m0 - 6 * g1 + 3 * m1
    assert np.any(leading < 0) and np.any(leading > 0)  # both kinds of cubic are drawn
    np.testing.assert_allclose(lowest, cubic.min(axis=0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(at, s[cubic.argmin(axis=0), 0], rtol=0, atol=1e-4)


@pytest.mark.slow
def test_a_lift_off_within_one_adaptive_step_is_located():
    dt = 0.05
    env = ll.make("CartPoleContinuous",
        cart_static_friction=0.3, cart_kinetic_friction=0.15, dt=dt, x_threshold=jnp.inf,
        theta_threshold_radians=jnp.inf,
        integrator=make_integrator("tsit5", diffrax.PIDController(rtol=1e-3, atol=1e-6)),
    )
    y0s = np.array([[0.0, 0.5, -0.35, 14.72], [0.0, 0.5, -0.35, 14.8]])
    with jax.enable_x64(True):
        evolve = jax.jit(jax.vmap(lambda y: env.evolve(ll.EnvState(y=y, steps=jnp.zeros((), int)), jnp.zeros(1))))
        states, info = evolve(jnp.asarray(y0s))
        modes = reference_modes(env)
        references = [modes_reference_step(modes, y0, np.zeros(1), dt) for y0 in y0s]
    for i, reference in enumerate(references):
        # The reference: the normal force changes sign twice, 13 and 24 ms apart.
        assert [which for _, which in reference.events] == [NORMAL_FLIPS, NORMAL_FLIPS]
        assert bool(info["solver_ok"][i]) and int(info["switches"][i]) == 2
        assert float(info["first_switch_time"][i]) == pytest.approx(reference.events[0][0], abs=1e-4)
        np.testing.assert_allclose(states.y[i], reference.y, rtol=0, atol=1e-5)
