"""The walled cart-pole with cart friction: impacts and stick-slip switches in one located-event loop,
against a SciPy reference of the same hybrid system written here from the equations of motion
(its own events, its own impact map), and its gradients against central differences.

Cart-pole (cart mass M_c, pole mass m, half length l, theta from upright towards +x):
    (M_c + m) x'' + m l cos(theta) theta'' - m l sin(theta) theta_dot^2 = F + f
    m l cos(theta) x'' + (4/3) m l^2 theta'' - m g l sin(theta) = 0
    N = (M_c + m) g - m l (theta'' sin(theta) + theta_dot^2 cos(theta))   (the rail's normal force)
slip in direction s: f = -mu_k s N (N > 0 here, checked); stick: x'' = 0, f what it takes, held
while |f| <= mu_s N. A wall at x = +-L: x_dot+ = -e x_dot-, and the impulse on x alone conserves
the pole's row of the momentum: m l cos(theta) dx_dot + (4/3) m l^2 dtheta_dot = 0.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import jacfwd_and_value, unforced_run_against
from scipy.integrate import solve_ivp

import lerax_like as ll
from lerax_like.analysis.modes_reference import modes_reference_step, reference_modes
from lerax_like.env import EnvState

G, CART, POLE, HALF = 9.8, 1.0, 0.1, 0.5
MU_S, MU_K, E, LIMIT = 0.2, 0.15, 0.8, 0.5
DT = 0.02


def _env(**settings):
    return ll.make("CartPoleContinuous",
        restitution=E, cart_kinetic_friction=MU_K, cart_static_friction=MU_S, track_limit=LIMIT,
        x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, dt=DT, **settings,
    )


def _tight():
    return _env(solver="dopri8", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=100_000)


def _slip(y, s, force):
    x, x_dot, theta, theta_dot = y
    c, si = np.cos(theta), np.sin(theta)
    a = np.array([[CART + POLE, POLE * HALF * c, MU_K * s], [POLE * HALF * c, 4 / 3 * POLE * HALF**2, 0.0], [0.0, POLE * HALF * si, 1.0]])
    b = np.array([force + POLE * HALF * si * theta_dot**2, POLE * G * HALF * si, (CART + POLE) * G - POLE * HALF * theta_dot**2 * c])
    x_acc, theta_acc, normal = np.linalg.solve(a, b)
    return x_acc, theta_acc, normal


def _stick(y, force):
    _, _, theta, theta_dot = y
    theta_acc = 3 * G * np.sin(theta) / (4 * HALF)
    friction = POLE * HALF * np.cos(theta) * theta_acc - POLE * HALF * np.sin(theta) * theta_dot**2 - force
    normal = (CART + POLE) * G - POLE * HALF * (theta_acc * np.sin(theta) + theta_dot**2 * np.cos(theta))
    return theta_acc, friction, normal


def reference(y0, t_end, force=0.0):
    """The hybrid solve with SciPy's DOP853 at rtol 1e-12, switching modes at located events."""
    t, y = 0.0, np.array(y0, dtype=float)
    s = float(np.sign(y[1]))
    assert s != 0

    def field(t, y):
        if s == 0:
            theta_acc, _, normal = _stick(y, force)
            assert normal > 0
            return [0.0, 0.0, y[3], theta_acc]
        x_acc, theta_acc, normal = _slip(y, s, force)
        assert normal > 0
        return [y[1], x_acc, y[3], theta_acc]

    def stops(t, y):
        return y[1] if s != 0 else 1.0

    def right_wall(t, y):
        return LIMIT - y[0]

    def left_wall(t, y):
        return y[0] + LIMIT

    def releases(t, y):
        if s != 0:
            return 1.0
        _, friction, normal = _stick(y, force)
        return MU_S * normal - abs(friction)

    for event in (stops, right_wall, left_wall, releases):
        event.terminal, event.direction = True, -1
    while t < t_end:
        stops.direction = -s if s != 0 else 0  # a slip's speed falls to zero (a reversal starts at zero)
        solution = solve_ivp(field, (t, t_end), y, method="DOP853", rtol=1e-12, atol=1e-12, events=(stops, right_wall, left_wall, releases))
        t, y = solution.t[-1], solution.y[:, -1].copy()
        fired = [len(times) > 0 for times in solution.t_events]
        if not any(fired):
            break
        if fired[0]:  # the slip ends
            y[1] = 0.0
            _, friction, normal = _stick(y, force)
            s = 0.0 if abs(friction) <= MU_S * normal else float(-np.sign(friction))
        elif fired[1] or fired[2]:  # a wall: Newton's restitution, the pole's momentum row conserved
            change = -(1 + E) * y[1]
            y[1] += change
            y[3] -= 3 * np.cos(y[2]) * change / (4 * HALF)
            s = float(np.sign(y[1]))
        else:  # released: slips in the direction of the load
            _, friction, _ = _stick(y, force)
            s = float(-np.sign(friction))
    return y


_evolve = eqx.filter_jit(lambda env, state: env.evolve(state, jnp.zeros(1)))


@pytest.mark.slow
def test_the_walled_cart_pole_with_friction_builds_steps_and_matches_scipy():
    env = _tight()
    assert env.contacts and env.friction
    _, impacts, switches = unforced_run_against(env, np.array([0.0, 1.5, 0.1, 0.0]), reference)
    assert impacts >= 1 and switches >= 2  # it hit the wall, stopped and slipped again


@pytest.mark.slow
def test_the_studies_reference_agrees_with_the_reference_typed_from_the_equations():
    # The studies' SciPy reference (`lerax_like.analysis.modes_reference`) runs the package's own
    # modes, guards and resets; `reference` above shares nothing with them but the equations.
    env = _env()
    y0 = np.array([0.0, 1.5, 0.1, 0.0])
    y, fired = y0, []
    for k in range(1, 101):
        step = modes_reference_step(reference_modes(env, (k - 1) * DT), y, np.zeros(1), DT)
        y, fired = step.y, fired + [which for _, which in step.events]
        if k % 25 == 0:
            np.testing.assert_allclose(y, reference(y0, k * DT), rtol=0, atol=1e-8, err_msg=f"t = {k * DT}")
    # Guards: the friction's four (0: a slip ends, 2: a stick releases), then the walls' gaps.
    assert 0 in fired and 2 in fired and any(which >= 4 for which in fired)


def _final(env, y0, steps=25):
    # One compiled step in a scan (a Python loop would compile 25 copies of the segment loop).
    def step(state, _):
        return env.evolve(state, jnp.zeros(1))[0], None

    state, _ = jax.lax.scan(step, EnvState(y=y0, steps=jnp.zeros((), int)), None, length=steps)
    return jnp.sum(state.y * jnp.array([1.0, 0.5, 1.0, 0.1]))


@pytest.mark.slow
def test_vmapped_gradient_through_impact_and_switches_matches_central_differences():
    starts = jnp.array([[0.0, speed, 0.1, 0.0] for speed in (1.4, 1.5, 1.6, 1.7)])
    env = _env(solver="dopri8", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=4096)
    reverse = jax.jit(jax.vmap(jax.grad(lambda y0: _final(env, y0))))(starts)
    forward_env = ll.with_adjoint(env, "forward")
    # Forward mode at each start and at its shifted copies, in one program: its values at the
    # shifted copies are the central differences' values.
    h = 1e-5
    shifts = np.concatenate([np.zeros((1, 4)), *[sign * h * np.eye(4)[i][None] for i in range(4) for sign in (1, -1)]])
    points = starts[:, None, :] + jnp.asarray(shifts)[None]  # (start, shift, state)
    # Every (start, shift) pair in one vmap: a vmap of a vmap batches the step twice over.
    forward_at = jax.vmap(jacfwd_and_value(lambda y0: (_final(forward_env, y0), ())))
    jacobians, (values, _) = jax.jit(forward_at)(points.reshape(-1, 4))
    jacobians, values = jacobians.reshape(points.shape), np.asarray(values).reshape(points.shape[:2])
    central = np.stack([(values[:, 1 + 2 * i] - values[:, 2 + 2 * i]) / (2 * h) for i in range(4)], axis=1)
    forward = jacobians[:, 0]
    np.testing.assert_allclose(reverse, central, rtol=0, atol=1e-5)
    np.testing.assert_allclose(forward, central, rtol=0, atol=1e-5)


@pytest.mark.slow
def test_a_block_slides_into_the_wall_at_the_end_of_its_plane_rebounds_and_sticks():
    # Level plane, kinetic mu: it reaches the wall (distance d) at v1 = sqrt(v0^2 - 2 mu g d),
    # rebounds at e v1, slides back (e v1)^2 / (2 mu g) and sticks there (no load).
    mu, g, e, d, v0 = 0.3, 9.81, 0.6, 0.5, 3.0
    env = ll.make("SlidingBlock",
        static_friction=0.5, kinetic_friction=mu, gravity=g, restitution=e, plane_end=d, dt=0.05,
        solver="dopri8", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=100_000,
    )
    state = EnvState(y=jnp.array([0.0, v0]), steps=jnp.zeros((), int))
    impacts = switches = 0
    for _ in range(40):
        state, info = _evolve(env, state)
        assert bool(info["solver_ok"])
        impacts += int(info["impacts"])
        switches += int(info["switches"])
    v1 = np.sqrt(v0**2 - 2 * mu * g * d)
    assert impacts == 1 and switches == 1
    position, speed = np.asarray(state.y)
    assert speed == 0.0
    assert abs(position - (d - (e * v1) ** 2 / (2 * mu * g))) < 1e-9
