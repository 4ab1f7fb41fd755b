"""The cart-pole with Coulomb friction on the cart (`CartFriction`) against an independent reference.

The reference is written here, not imported: Florian's corrected equations ("Correct equations
for the dynamics of the cart-pole system", R. V. Florian, 2005/2007) in closed form, with the
normal force `N_c` and `sgn(N_c x_dot)`, solved by SciPy's DOP853 at rtol = atol = 1e-13 with
its own events for the mode switches (the slip speed reaching zero, `N_c` changing sign, a
stick's force reaching `mu_s |N_c|`), restarted at each. Note: solving Florian's three
equations (cart, pole, normal force) for the accelerations gives the denominator of
`theta''` as `l (4/3 - m cos(theta) / (m_c + m) (cos(theta) - mu_c S sin(theta)))`, `S = sgn(N_c
x_dot)`; the form often reproduced without the `sin(theta)` does not solve them (SymPy, below).

Also: the failure modes on the cart-pole (a step that needs more switches than `max_events`,
and a slip that no friction force makes consistent, Painleve's case), reported in
`info["solver_ok"]` and `info["friction_consistent"]`, never silent.
"""

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll


MU_S, MU_K, CART, POLE, HALF, G = 0.5, 0.4, 1.0, 0.5, 0.5, 9.8
DT, STEPS = 0.02, 500
# A pole spinning at 12 rad/s from 0.3 rad: over the top its centrifugal pull lifts the cart
# (N_c < 0 in the first steps: the sign change), the cart slides, stops and sticks while the
# pole swings, and is pushed off again by the swing and by the force 3 sin(0.05 k) N.
Y0 = np.array([0.0, 0.0, 0.3, 12.0])
FORCES = 3.0 * np.sin(0.05 * np.arange(STEPS))


def _slip(theta, omega, force, s_n):
    """Florian's slip accelerations and normal force, `s_n = sgn(N_c x_dot)`."""
    total, ml = CART + POLE, POLE * HALF
    sin, cos = np.sin(theta), np.cos(theta)
    theta_acc = (
        G * sin + cos * ((-force - ml * omega**2 * (sin + MU_K * s_n * cos)) / total + MU_K * G * s_n)
    ) / (HALF * (4 / 3 - POLE * cos / total * (cos - MU_K * s_n * sin)))
    normal = total * G - ml * (theta_acc * sin + omega**2 * cos)
    x_acc = (force + ml * (omega**2 * sin - theta_acc * cos) - MU_K * normal * s_n) / total
    return x_acc, theta_acc, normal


def _stick(theta, omega, force):
    """The cart held (`x'' = 0`): the pole's acceleration, the rail's holding force, `N_c`."""
    ml = POLE * HALF
    sin, cos = np.sin(theta), np.cos(theta)
    theta_acc = 3 * G * sin / (4 * HALF)
    hold = ml * (theta_acc * cos - omega**2 * sin) - force
    normal = (CART + POLE) * G - ml * (theta_acc * sin + omega**2 * cos)
    return theta_acc, hold, normal


def _reference_step(y, force):
    """One env step of the reference, from `y`, restarting the solve at each switch."""
    from scipy.integrate import solve_ivp

    t, y, switches = 0.0, np.array(y, dtype=float), 0

    def start_mode(y):
        _, hold, normal = _stick(y[2], y[3], force)
        if y[1] == 0.0:
            if abs(hold) <= MU_S * abs(normal):
                return 0.0, np.sign(normal)
            s = -np.sign(hold)
        else:
            s = np.sign(y[1])
        # The slip's N_c has the sign of the frictionless one (the consistent case).
        return s, np.sign(_slip(y[2], y[3], force, 0.0)[2])

    s, sigma = start_mode(y)
    while t < DT:
        if s == 0:
            def rhs(t, y):
                theta_acc, _, _ = _stick(y[2], y[3], force)
                return [0.0, 0.0, y[3], theta_acc]

            def release(t, y):
                _, hold, normal = _stick(y[2], y[3], force)
                return MU_S * abs(normal) - abs(hold)

            events = [release]
        else:
            def rhs(t, y, s=s, sigma=sigma):
                x_acc, theta_acc, _ = _slip(y[2], y[3], force, sigma * s)
                return [y[1], x_acc, y[3], theta_acc]

            def stops(t, y, s=s):
                return s * y[1]

            def flips(t, y, s=s, sigma=sigma):
                return sigma * _slip(y[2], y[3], force, sigma * s)[2]

            events = [stops, flips]
        for event in events:
            event.terminal, event.direction = True, -1
        solution = solve_ivp(rhs, (t, DT), y, method="DOP853", rtol=1e-13, atol=1e-13, events=events)
        assert solution.status >= 0, solution.message
        hit = [(solution.t_events[i][0], i) for i in range(len(events)) if len(solution.t_events[i])]
        if not hit:
            return solution.y[:, -1], switches
        t, which = min(hit)
        y = solution.y_events[which][0].copy()
        switches += 1
        _, hold, normal = _stick(y[2], y[3], force)
        if s == 0:  # released: slides in the direction of the load
            s, sigma = -np.sign(hold), np.sign(normal)
        elif which == 0:  # the slip speed reached zero: stick if it can be held, else reverse
            y[1] = 0.0
            s, sigma = (0.0 if abs(hold) <= MU_S * abs(normal) else -np.sign(hold)), np.sign(normal)
        else:  # N_c changed sign
            sigma = -sigma
    return y, switches


@pytest.mark.slow
def test_florians_theta_equation_solves_his_three_equations():
    import sympy as sp

    theta, omega, force, s_n, x_acc, theta_acc, normal = sp.symbols("theta omega F S xdd tdd N")
    m, mc, l, g, mu = sp.symbols("m m_c l g mu", positive=True)
    total = m + mc
    cart = sp.Eq(total * x_acc + m * l * sp.cos(theta) * theta_acc - m * l * omega**2 * sp.sin(theta), force - mu * normal * s_n)
    pole = sp.Eq(m * l * sp.cos(theta) * x_acc + sp.Rational(4, 3) * m * l**2 * theta_acc, m * g * l * sp.sin(theta))
    rail = sp.Eq(normal, total * g - m * l * (theta_acc * sp.sin(theta) + omega**2 * sp.cos(theta)))
    solution = sp.solve([cart, pole, rail], [x_acc, theta_acc, normal], dict=True)[0]
    closed = (
        g * sp.sin(theta)
        + sp.cos(theta) * ((-force - m * l * omega**2 * (sp.sin(theta) + mu * s_n * sp.cos(theta))) / total + mu * g * s_n)
    ) / (l * (sp.Rational(4, 3) - m * sp.cos(theta) / total * (sp.cos(theta) - mu * s_n * sp.sin(theta))))
    assert sp.simplify(solution[theta_acc] - closed) == 0


def _env(**keywords):
    return ll.make("CartPoleContinuous",
        cart_static_friction=MU_S, cart_kinetic_friction=MU_K, pole_mass=POLE, cart_mass=CART, half_length=HALF,
        gravity=G, dt=DT, x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, solver="tsit5",
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=4096, **keywords,
    )


@pytest.mark.slow
def test_friction_cartpole_matches_an_event_located_reference_of_florians_equations():
    env = _env()
    actions = jnp.asarray(FORCES / float(env.force_mag))[:, None]
    state = ll.EnvState(y=jnp.asarray(Y0), steps=jnp.zeros((), dtype=int))
    ys, info = jax.jit(ll.rollout)(env, state, actions)
    assert bool(jnp.all(info["solver_ok"]))
    y, reference, switches, normal_signs, stuck = Y0, [], 0, set(), 0
    for k in range(STEPS):
        y, n = _reference_step(y, FORCES[k])
        reference.append(y)
        switches += n
        stuck += y[1] == 0.0
        normal_signs.add(np.sign(_slip(y[2], y[3], FORCES[k], 0.0)[2]))
    reference = np.array(reference)
    # The run has what it is chosen for: stick-slip switches and both signs of N_c.
    assert switches >= 2 and stuck >= 1 and normal_signs == {-1.0, 1.0}
    assert int(jnp.sum(info["switches"])) == switches
    np.testing.assert_allclose(np.asarray(ys), reference, rtol=0, atol=1e-9)


@pytest.mark.slow
def test_more_switches_in_a_step_than_the_budget_fail_the_step():
    # The spinning pole's first steps: the cart starts at rest, is released at once and
    # its N_c changes sign within the first few steps; find a step with two switches and
    # give it a budget of one.
    env = _env()
    step = jax.jit(lambda e, s, u: e.evolve(s, u))
    state = ll.EnvState(y=jnp.asarray(Y0), steps=jnp.zeros((), dtype=int))
    for k in range(STEPS):
        after, info = step(env, state, jnp.array([FORCES[k]]))
        assert bool(info["solver_ok"])
        if int(info["switches"]) >= 2:
            break
        state = after
    else:
        pytest.fail("no step with two switches")
    tight = _env(max_events=1)
    failed, info = step(tight, state, jnp.array([FORCES[k]]))
    assert not bool(info["solver_ok"]) and bool(info["friction_consistent"])
    assert np.array_equal(np.asarray(failed.y), np.asarray(state.y))  # the pre-step state kept


@pytest.mark.slow
def test_an_inconsistent_slip_is_reported_not_integrated():
    # Painleve: a heavy pole at 45 degrees on a light cart with mu = 2 (the slip's friction
    # grows with the normal force faster than the normal force allows): one direction of
    # slip has no consistent friction force. The other direction is integrated.
    env = ll.make("CartPoleContinuous",
        cart_static_friction=2.0, cart_kinetic_friction=2.0, pole_mass=1.0, cart_mass=0.01,
        x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, solver="tsit5",
    )
    states = ll.EnvState(y=jnp.array([[0.0, 1.0, np.pi / 4, 0.0], [0.0, -1.0, np.pi / 4, 0.0]]), steps=jnp.zeros(2, dtype=int))
    after, info = jax.jit(jax.vmap(lambda s: env.evolve(s, jnp.zeros(1))))(states)
    consistent = np.asarray(info["friction_consistent"])
    assert consistent.tolist().count(False) == 1
    assert np.array_equal(np.asarray(info["solver_ok"]), consistent)
    bad = int(np.argmin(consistent))
    assert np.array_equal(np.asarray(after.y[bad]), np.asarray(states.y[bad]))
    assert np.all(np.isfinite(np.asarray(after.y)))


def test_zero_friction_builds_no_add_on_and_stays_the_plain_cartpole_bit_for_bit():
    # Coefficients given as zero build nothing (the scene computes no friction), so the
    # cart-pole stays the plain one, which tests/test_cartpole_gymnasium.py holds to Gymnasium.
    plain, zero = ll.CartPole(), ll.make("CartPole", cart_static_friction=0.0, cart_kinetic_friction=0.0)
    assert zero.friction == () and plain.friction == ()
    assert ll.make("CartPole", cart_kinetic_friction=0.0).friction != ()  # static friction left at Barto's
    state = ll.EnvState(y=jnp.array([0.01, -0.02, 0.03, 0.04]), steps=jnp.zeros((), dtype=int))
    actions = jnp.array([0, 1, 1, 0, 1, 0, 0, 1] * 4)
    run = jax.jit(ll.rollout)
    assert np.array_equal(np.asarray(run(zero, state, actions)[0]), np.asarray(run(plain, state, actions)[0]))


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_the_double_cart_poles_rail_force_is_the_weight_less_the_links_vertical_accelerations():
    # N = (m_c + m_1 + m_2) g + m_1 h_1'' + m_2 h_2'', the heights of the uniform poles' centres
    # written out (h_1 = l_1 cos(t_1) / 2, h_2 = l_1 cos(t_1) + l_2 cos(t_2) / 2), against
    # CartFriction's normal force, read off the chain's potential energy.
    env = ll.make("DoubleCartPole", cart_static_friction=0.3, cart_kinetic_friction=0.2, pole_masses=jnp.array([0.4, 0.3]))
    chain, friction = env.dynamics, env.friction[0]
    y = jnp.array([0.1, 0.7, -1.2, 0.3, 2.0, -3.0])  # [x, t1, t2, x', t1', t2']
    acceleration = jnp.array([0.5, -4.0, 6.0])  # any: N is affine in it
    (m1, m2), (l1, l2) = chain.pole_masses, chain.pole_lengths

    def heights(q):
        return jnp.stack([l1 * jnp.cos(q[1]) / 2, l1 * jnp.cos(q[1]) + l2 * jnp.cos(q[2]) / 2])

    q, rates = y[:3], y[3:]
    _, curvature = jax.jvp(lambda p: jax.jacfwd(heights)(p) @ rates, (q,), (rates,))
    vertical = jax.jacfwd(heights)(q) @ acceleration + curvature
    expected = (chain.cart_mass + m1 + m2) * chain.gravity + m1 * vertical[0] + m2 * vertical[1]
    assert abs(float(friction.normal_force(chain, y, acceleration)) - float(expected)) <= 1e-12 * abs(float(expected))
