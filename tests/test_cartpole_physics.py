"""CartPoleDynamics against Gymnasium's equations, a SymPy Lagrangian, and conservation laws."""

import diffrax
import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy

import lerax_like as ll


def _gymnasium_accelerations(state, force_sign, *, masspole=0.1, length=0.5, masscart=1.0, gravity=9.8):
    """Gymnasium's own step with tau = 1, from which x_acc and theta_acc are read off exactly.

    With tau = 1, x_dot' = x_dot + x_acc, so x_acc = x_dot' - x_dot up to one rounding.
    """
    env = gymnasium.make("CartPole-v1").unwrapped
    env.reset(seed=0)
    env.masspole, env.length, env.masscart, env.gravity = masspole, length, masscart, gravity
    # Gymnasium caches these in __init__.
    env.total_mass = env.masspole + env.masscart
    env.polemass_length = env.masspole * env.length
    env.tau = 1.0
    env.state = np.array(state, dtype=np.float64)
    env.step(1 if force_sign > 0 else 0)
    return env.state[1] - state[1], env.state[3] - state[3]


def _random_states(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform([-2, -3, -np.pi, -5], [2, 3, np.pi, 5], size=(n, 4))


def test_vector_field_equals_gymnasium_equations():
    dynamics = ll.CartPoleDynamics()
    vector_field = eqx.filter_jit(dynamics.vector_field)
    for state in _random_states(20, 0):
        for sign in (-1, 1):
            x_acc, theta_acc = _gymnasium_accelerations(state, sign)
            dy = np.asarray(vector_field(0.0, jnp.asarray(state), jnp.array([10.0 * sign])))
            np.testing.assert_allclose(dy, [state[1], x_acc, state[3], theta_acc], rtol=1e-12, atol=1e-13)


def test_vector_field_follows_parameters_swapped_by_tree_at():
    dynamics = ll.CartPoleDynamics()
    heavier = eqx.tree_at(lambda d: d.pole_mass, dynamics, jnp.asarray(0.7))
    longer = eqx.tree_at(lambda d: d.half_length, heavier, jnp.asarray(1.3))
    vector_field = jax.jit(lambda d, y, u: d.vector_field(0.0, y, u))
    for state in _random_states(10, 1):
        x_acc, theta_acc = _gymnasium_accelerations(state, 1, masspole=0.7, length=1.3)
        dy = np.asarray(vector_field(longer, jnp.asarray(state), jnp.array([10.0])))
        np.testing.assert_allclose(dy[[1, 3]], [x_acc, theta_acc], rtol=1e-12, atol=1e-13)
    # The derived total mass follows the swap (it is computed, never stored).
    assert float(longer.total_mass) == pytest.approx(1.7)


def _sympy_cartpole():
    """Euler-Lagrange for a cart and a uniform rod (half length l, inertia m l^2 / 3 about its centre)."""
    t = sympy.symbols("t")
    M, m, l, g, F = sympy.symbols("M m l g F", positive=True)
    x = sympy.Function("x")(t)
    theta = sympy.Function("theta")(t)
    com_x = x + l * sympy.sin(theta)
    com_y = l * sympy.cos(theta)
    kinetic = (
        M * x.diff(t) ** 2 / 2
        + m * (com_x.diff(t) ** 2 + com_y.diff(t) ** 2) / 2
        + (m * l**2 / 3) * theta.diff(t) ** 2 / 2
    )
    lagrangian = kinetic - m * g * com_y
    equations = [
        sympy.diff(lagrangian.diff(q.diff(t)), t) - lagrangian.diff(q) - force
        for q, force in [(x, F), (theta, 0)]
    ]
    accelerations = sympy.solve(equations, [x.diff(t, 2), theta.diff(t, 2)], dict=True)[0]
    X, Xd, Th, Thd = sympy.symbols("X Xd Th Thd")
    substitutions = {x.diff(t): Xd, theta.diff(t): Thd, x: X, theta: Th}
    expressions = [accelerations[x.diff(t, 2)].subs(substitutions), accelerations[theta.diff(t, 2)].subs(substitutions)]
    return sympy.lambdify((X, Xd, Th, Thd, F, M, m, l, g), expressions, "numpy")


def test_vector_field_equals_sympy_lagrangian():
    accelerations = _sympy_cartpole()
    rng = np.random.default_rng(2)
    vector_field = jax.jit(lambda d, y, u: d.vector_field(0.0, y, u))
    for state in _random_states(10, 3):
        cart_mass, pole_mass, half_length, gravity, force = rng.uniform([0.5, 0.05, 0.2, 5, -20], [3, 2, 2, 12, 20])
        dynamics = ll.CartPoleDynamics(gravity=gravity, cart_mass=cart_mass, pole_mass=pole_mass, half_length=half_length)
        dy = np.asarray(vector_field(dynamics, jnp.asarray(state), jnp.array([force])))
        x_acc, theta_acc = accelerations(*state, force, cart_mass, pole_mass, half_length, gravity)
        np.testing.assert_allclose(dy, [state[1], x_acc, state[3], theta_acc], rtol=1e-11, atol=1e-12)


def test_energy_and_momentum_conserved_without_force():
    dynamics = ll.CartPoleDynamics(pole_mass=0.4)
    y0 = jnp.array([0.1, 0.3, 2.5, -1.0])
    integrator = ll.make_integrator("tsit5", diffrax.PIDController(rtol=1e-11, atol=1e-12), max_steps=100_000)
    y1, info = integrator.integrate(dynamics.vector_field, y0, jnp.zeros(1), 5.0)
    assert bool(info["solver_ok"])
    assert abs(float(dynamics.energy(y1) - dynamics.energy(y0))) < 1e-9 * abs(float(dynamics.energy(y0)))
    assert abs(float(dynamics.momentum(y1) - dynamics.momentum(y0))) < 1e-9
    # And energy really is the quantity the vector field conserves: its time derivative vanishes.
    energy_rate = jax.jvp(dynamics.energy, (y0,), (dynamics.vector_field(0.0, y0, jnp.zeros(1)),))[1]
    assert abs(float(energy_rate)) < 1e-12


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_upright_is_an_unstable_equilibrium_and_hanging_a_stable_one():
    dynamics = ll.CartPoleDynamics()
    zero = jnp.zeros(1)
    # float64 pi is off by 1.2e-16, so sin(pi) is too: the hanging acceleration is
    # g * 1.2e-16 / (4/3 l) ~ 2e-15, not zero.
    for theta in (0.0, np.pi):
        assert np.allclose(dynamics.vector_field(0.0, jnp.array([0.0, 0.0, theta, 0.0]), zero), 0.0, atol=1e-14)
    jacobian_up = jax.jacfwd(lambda y: dynamics.vector_field(0.0, y, zero))(jnp.zeros(4))
    jacobian_down = jax.jacfwd(lambda y: dynamics.vector_field(0.0, y, zero))(jnp.array([0.0, 0.0, np.pi, 0.0]))
    assert np.max(np.linalg.eigvals(np.asarray(jacobian_up)).real) > 1.0
    assert np.max(np.linalg.eigvals(np.asarray(jacobian_down)).real) < 1e-9
