"""Stiff scenes and the solvers that work on them.

Van der Pol at mu = 1e3 against SciPy's Radau; the stiff cart-pole options (hinge
damping, end stops) against a SymPy derivation and their eigenvalues; fixed-step implicit
solves; and where autodiff through the contact stops agreeing with finite differences.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll

from conftest import relative_error


def _rollout_info(env, y0, steps):
    state = ll.EnvState(y=jnp.asarray(y0), steps=jnp.zeros((), dtype=int))
    actions = jnp.zeros((steps, 1))
    return eqx.filter_jit(ll.rollout)(env, state, actions, key=jax.random.key(0))


def _van_der_pol_reference(mu, y0, t1):
    from scipy.integrate import solve_ivp

    def vector_field(t, y):
        x, v = y
        return [v, mu * (1 - x * x) * v - x]

    def jacobian(t, y):
        x, v = y
        return [[0.0, 1.0], [-2 * mu * x * v - 1, mu * (1 - x * x)]]

    solution = solve_ivp(
        vector_field, (0.0, t1), y0, method="Radau", rtol=1e-12, atol=1e-12, jac=jacobian
    )
    assert solution.success
    return solution.y[:, -1]


@pytest.mark.slow
def test_van_der_pol_kvaerno5_reaches_t3000_as_radau():
    env = ll.VanDerPol(mu=1000.0, dt=10.0, solver="kvaerno5")
    ys, infos = _rollout_info(env, [2.0, 0.0], 300)
    assert bool(jnp.all(infos["solver_ok"]))
    # About 20 accepted steps per env step of 10 s, not the ~1e4 an explicit solver needs.
    assert int(jnp.max(infos["solver_steps"])) < 200
    reference = _van_der_pol_reference(1000.0, [2.0, 0.0], 3000.0)
    # Relative per component: the velocity is small (~1e-3) at t = 3000, on a slow branch.
    np.testing.assert_allclose(np.asarray(ys[-1]), reference, rtol=1e-3)


def test_van_der_pol_tsit5_reports_exhausted_budget_without_raising():
    env = ll.VanDerPol(mu=1000.0, dt=10.0, solver=ll.make_integrator("tsit5", max_steps=64))
    state = ll.EnvState(y=jnp.array([2.0, 0.0]), steps=jnp.zeros((), dtype=int))
    step = eqx.filter_jit(lambda env, state, key: env.step(state, jnp.zeros(1), key=key))
    next_state, observation, reward, terminated, truncated, info = step(env, state, jax.random.key(1))
    assert not bool(info["solver_ok"])
    assert int(info["solver_steps"]) <= 64
    assert bool(terminated) and not bool(truncated)
    assert bool(jnp.all(jnp.isfinite(observation))) and bool(jnp.isfinite(reward))
    # The autoreset started a fresh episode.
    assert int(next_state.steps) == 0
    np.testing.assert_array_equal(np.asarray(info["final_observation"]), [2.0, 0.0])


def test_fixed_step_implicit_needs_explicit_root_finder_tolerances():
    with pytest.raises(ValueError, match="tolerances"):
        ll.Integrator(diffrax.Kvaerno5(), diffrax.ConstantStepSize())
    # The presets give their root finder explicit tolerances under a constant step size.
    integrator = ll.make_integrator("implicit_euler", diffrax.ConstantStepSize(), substeps=100)
    dynamics = ll.VanDerPolDynamics(mu=1000.0)
    y1, info = eqx.filter_jit(integrator.integrate)(
        dynamics.vector_field, jnp.array([2.0, 0.0]), jnp.zeros(1), 1.0
    )
    assert bool(info["solver_ok"])
    # Implicit Euler is first order: h = 0.01 on the slow branch costs about 1e-5.
    assert relative_error(y1[0], _van_der_pol_reference(1000.0, [2.0, 0.0], 1.0)[0]) < 1e-4


def _lagrange_accelerations():
    """Cart-pole accelerations from Lagrange's equations with generalised forces, by SymPy."""
    import sympy as sp

    t = sp.symbols("t")
    cart_mass, pole_mass, half_length, gravity, damping, force = sp.symbols(
        "M_c m l g b F", positive=True
    )
    x, theta = sp.Function("x")(t), sp.Function("theta")(t)
    # Centre of the pole, theta from upright and positive towards +x.
    pole_x, pole_z = x + half_length * sp.sin(theta), half_length * sp.cos(theta)
    inertia = pole_mass * half_length**2 / 3
    kinetic = (
        cart_mass * x.diff(t) ** 2 / 2
        + pole_mass * (pole_x.diff(t) ** 2 + pole_z.diff(t) ** 2) / 2
        + inertia * theta.diff(t) ** 2 / 2
    )
    lagrangian = kinetic - pole_mass * gravity * pole_z
    # Generalised forces: the horizontal force (input plus end stops) on x; the hinge
    # friction torque on theta (it acts between cart and pole, whose relative angle is theta).
    generalised = {x: force, theta: -damping * theta.diff(t)}
    equations = [
        sp.Eq(lagrangian.diff(q.diff(t)).diff(t) - lagrangian.diff(q), generalised[q]) for q in (x, theta)
    ]
    x_acc, theta_acc = sp.symbols("x_acc theta_acc")
    x_dot, theta_dot, x_pos, angle = sp.symbols("x_dot theta_dot x_pos angle")
    replacements = [
        (x.diff(t, 2), x_acc), (theta.diff(t, 2), theta_acc),
        (x.diff(t), x_dot), (theta.diff(t), theta_dot), (x, x_pos), (theta, angle),
    ]
    equations = [equation.subs(replacements) for equation in equations]
    solution = sp.solve(equations, [x_acc, theta_acc], dict=True)[0]
    arguments = (angle, theta_dot, cart_mass, pole_mass, half_length, gravity, damping, force)
    return sp.lambdify(arguments, [solution[x_acc], solution[theta_acc]], "numpy")


def test_stiff_cartpole_equations_match_lagrange_with_generalised_forces():
    accelerations = _lagrange_accelerations()
    rng = np.random.default_rng(0)
    vector_field = jax.jit(lambda dynamics, y, u: dynamics.vector_field(0.0, y, u))
    for _ in range(20):
        cart_mass, pole_mass = rng.uniform(0.1, 3.0), rng.uniform(0.01, 2.0)
        half_length, damping = rng.uniform(0.1, 2.0), rng.uniform(0.0, 300.0)
        stiffness, stop_damping = rng.uniform(0.0, 1e6), rng.uniform(0.0, 1e3)
        track_limit = 2.4
        # Half the states in contact with one stop or the other.
        y = np.array([rng.uniform(-2.5, 2.5), rng.normal(), rng.uniform(-np.pi, np.pi), rng.normal()])
        u = rng.normal()
        dynamics = ll.CartPoleDynamics(
            cart_mass=cart_mass, pole_mass=pole_mass, half_length=half_length, joint_damping=damping,
            end_stop_stiffness=stiffness, end_stop_damping=stop_damping, track_limit=track_limit,
        )
        # The end stops: one-sided spring-dampers that push and never pull.
        x, x_dot = y[0], y[1]
        stop = 0.0
        if x > track_limit:
            stop = -max(stiffness * (x - track_limit) + stop_damping * x_dot, 0.0)
        elif x < -track_limit:
            stop = max(stiffness * (-track_limit - x) - stop_damping * x_dot, 0.0)
        x_acc, theta_acc = accelerations(
            y[2], y[3], cart_mass, pole_mass, half_length, 9.8, damping, u + stop
        )
        derivative = np.asarray(vector_field(dynamics, jnp.asarray(y), jnp.array([u])))
        np.testing.assert_allclose(derivative, [y[1], x_acc, y[3], theta_acc], rtol=1e-10, atol=1e-9)


def test_joint_damping_eigenvalue():
    # b = 300 on the default cart-pole: the fast eigenvalue is -b over the pole's effective
    # inertia about the hinge with the cart free, m l^2 (4/3 - m / (M + m)): about -1e4.
    dynamics = ll.CartPoleDynamics(joint_damping=300.0)
    jacobian = jax.jacfwd(lambda y: dynamics.vector_field(0.0, y, jnp.zeros(1)))(jnp.zeros(4))
    fastest = float(np.min(np.linalg.eigvals(np.asarray(jacobian)).real))
    m, l, total = 0.1, 0.5, 1.1
    expected = -300.0 / (m * l**2 * (4 / 3 - m / total))
    assert expected == pytest.approx(-9657, rel=1e-3)
    # Gravity shifts it by ~g/(b/I) relative, far below 1e-3.
    assert fastest == pytest.approx(expected, rel=1e-3)


def test_stiff_options_off_keep_the_vector_field_bitwise():
    # With the stiff options at 0 the added terms are exact zeros.
    plain = ll.CartPoleDynamics()
    stiff_off = ll.CartPoleDynamics(joint_damping=0.0, end_stop_stiffness=0.0, end_stop_damping=0.0)

    def gymnasium(y, force):  # Gymnasium's CartPole-v1 arithmetic, in its order
        _, _, theta, theta_dot = y
        total_mass, polemass_length = 1.1, 0.1 * 0.5
        temp = (force + polemass_length * theta_dot**2 * jnp.sin(theta)) / total_mass
        thetaacc = (9.8 * jnp.sin(theta) - jnp.cos(theta) * temp) / (
            0.5 * (4.0 / 3.0 - 0.1 * jnp.cos(theta) ** 2 / total_mass)
        )
        xacc = temp - polemass_length * thetaacc * jnp.cos(theta) / total_mass
        return jnp.stack([y[1], xacc, y[3], thetaacc])

    ys = jax.random.uniform(jax.random.key(0), (64, 4), minval=-3.0, maxval=3.0)
    forces = jnp.where(jnp.arange(64) % 2 == 0, 10.0, -10.0)
    ours = jax.vmap(lambda y, f: stiff_off.vector_field(0.0, y, f[None]))(ys, forces)
    theirs = jax.vmap(gymnasium)(ys, forces)
    base = jax.vmap(lambda y, f: plain.vector_field(0.0, y, f[None]))(ys, forces)
    np.testing.assert_array_equal(np.asarray(ours), np.asarray(base))
    np.testing.assert_allclose(np.asarray(ours), np.asarray(theirs), rtol=1e-14, atol=1e-14)


def test_gradient_through_contact_disagrees_with_finite_differences():
    """Where autodiff through the solver is right near the end stop, and where not.

    Final cart velocity after 0.5 s against the initial position, the cart moving at
    1 m/s towards a stop at x = 1 (contact iff x0 > 0.5). Off contact autodiff and
    finite differences agree. With a damped stop (c > 0) the force jumps at impact: the
    flow's derivative gains a saltation term (the jump times the sensitivity of the
    impact time) that differentiating the solver's arithmetic cannot see, so autodiff is
    wrong by O(1) although the flow is smooth there (finite differences converge).
    Expected behaviour of non-smooth dynamics, not a bug: use finite differences, a
    smoothed contact, or event-located solves for gradients through impacts.
    """
    integrator = ll.make_integrator("tsit5", diffrax.PIDController(rtol=1e-10, atol=1e-12))

    def final_velocity(dynamics, x0):
        y0 = jnp.stack([x0, jnp.ones_like(x0), jnp.zeros_like(x0), jnp.zeros_like(x0)])
        y1, _ = integrator.integrate(dynamics.vector_field, y0, jnp.zeros(1), 0.5)
        return y1[1]

    value_and_grad = eqx.filter_jit(jax.vmap(jax.value_and_grad(final_velocity, argnums=1), in_axes=(None, 0)))
    dynamics = ll.CartPoleDynamics(end_stop_stiffness=1e4, end_stop_damping=100.0, track_limit=1.0)
    x0 = jnp.array([0.3, 0.6])  # no contact; bounced off the stop before t = 0.5
    steps = (1e-4, 1e-5)
    # One compiled batch: the points and their finite-difference neighbours.
    points = jnp.concatenate([x0] + [x0 + sign * h for h in steps for sign in (1, -1)])
    all_values, all_autodiff = value_and_grad(dynamics, points)
    values, autodiff = all_values[:2], all_autodiff[:2]
    finite = {
        h: (all_values[2 + 4 * i : 4 + 4 * i] - all_values[4 + 4 * i : 6 + 4 * i]) / (2 * h)
        for i, h in enumerate(steps)
    }
    # No contact: both derivatives are 0 (the cart coasts), and agree.
    assert float(values[0]) == pytest.approx(1.0, abs=1e-12)
    assert abs(float(autodiff[0])) < 1e-9 and abs(float(finite[1e-4][0])) < 1e-9
    # After the bounce the finite differences have converged (two step sizes agree)...
    assert float(values[1]) < 0
    assert float(finite[1e-4][1]) == pytest.approx(float(finite[1e-5][1]), rel=2e-2, abs=2e-3)
    # ...and autodiff is off by far more than the derivative itself.
    assert abs(float(autodiff[1]) - float(finite[1e-5][1])) > 10 * abs(float(finite[1e-5][1])) + 1.0
