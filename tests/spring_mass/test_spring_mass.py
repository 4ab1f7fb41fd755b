"""The spring-mass's physics against the closed form of the damped harmonic oscillator."""

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll

from .scene import SpringMass


def _closed_form(t, x0, v0, mass, stiffness, damping, force):
    """`x(t)`, `x'(t)` of `m x'' + c x' + k x = F` (F constant), under- or overdamped."""
    omega = math.sqrt(stiffness / mass)
    zeta = damping / (2 * math.sqrt(stiffness * mass))
    offset = x0 - force / stiffness  # from the equilibrium F / k
    if zeta < 1:
        decay, omega_d = zeta * omega, omega * math.sqrt(1 - zeta**2)
        a, b = offset, (v0 + decay * offset) / omega_d
        envelope = np.exp(-decay * t)
        x = envelope * (a * np.cos(omega_d * t) + b * np.sin(omega_d * t))
        v = envelope * ((b * omega_d - decay * a) * np.cos(omega_d * t) - (a * omega_d + decay * b) * np.sin(omega_d * t))
    else:
        root = omega * math.sqrt(zeta**2 - 1)
        fast, slow = -zeta * omega - root, -zeta * omega + root
        c_fast = (v0 - slow * offset) / (fast - slow)
        c_slow = offset - c_fast
        x = c_fast * np.exp(fast * t) + c_slow * np.exp(slow * t)
        v = fast * c_fast * np.exp(fast * t) + slow * c_slow * np.exp(slow * t)
    return x + force / stiffness, v


# One compilation for the three cases: the parameters are leaves, not static.
_rollout = eqx.filter_jit(ll.rollout)


@pytest.mark.parametrize(
    "damping, action", [(0.0, 0.0), (0.4, 0.7), (5.0, -0.7)], ids=["undamped", "underdamped", "overdamped"]
)
def test_a_constant_force_follows_the_closed_form(damping, action):
    mass, stiffness, force_mag = 1.5, 4.0, 2.0
    integrator = ll.make_integrator("dopri8", diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=10_000)
    env = ll.make(SpringMass, mass=mass, stiffness=stiffness, damping=damping, force_mag=force_mag, integrator=integrator)
    x0, v0, steps = 0.8, -0.3, 60
    state = ll.EnvState(y=jnp.array([x0, v0]), steps=jnp.asarray(0))
    ys, info = _rollout(env, state, jnp.full((steps, 1), action))
    assert np.all(np.asarray(info["solver_ok"]))
    times = float(env.dt) * np.arange(1, steps + 1)
    x, v = _closed_form(times, x0, v0, mass, stiffness, damping, force_mag * action)
    np.testing.assert_allclose(np.asarray(ys), np.stack([x, v], axis=1), rtol=0, atol=1e-10)


def test_energy_decays_at_the_damping_rate():
    # d/dt (m v^2 / 2 + k x^2 / 2) = -c v^2 with no force: the vector field against the energy's
    # derivative by the chain rule, at random states.
    dynamics = SpringMass().dynamics
    for y in np.random.default_rng(0).normal(size=(5, 2)):
        y = jnp.asarray(y)
        x_dot, x_acc = dynamics.vector_field(0.0, y, jnp.zeros(1))
        rate = dynamics.mass * y[1] * x_acc + dynamics.stiffness * y[0] * x_dot
        np.testing.assert_allclose(float(rate), float(-dynamics.damping * y[1] ** 2), rtol=1e-12)


@pytest.mark.slow  # 4.4 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_it_is_registered_with_no_line_changed_in_the_package():
    assert ll.SCENES["SpringMass"] is SpringMass
    assert not hasattr(ll, "SpringMass")  # registered, not part of the package's names
