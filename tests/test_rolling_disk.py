"""RollingDisk against closed forms derived by hand (not from the code under test).

A uniform disk (I = m r^2 / 2) launched sliding at v0 with no spin on a floor of kinetic
coefficient mu: the friction force -mu m g decelerates the centre (x'' = -mu g) and spins
the disk up (I angle'' = r mu m g), so the slip w = x_dot - r angle_dot falls at
w' = -mu g (1 + m r^2 / I) = -3 mu g; rolling begins at t* = v0 / (3 mu g) at speed
v0 - mu g t* = 2 v0 / 3. Past t*: x(T) = v0 t* - mu g t*^2 / 2 + (2 v0 / 3)(T - t*)
= v0^2 / (18 mu g) + 2 v0 T / 3, so dx(T)/dmu = -v0^2 / (18 mu^2 g).

Impacts: a disk falling at vertical speed -c onto the floor gets the normal impulse
J_n = (1 + e) m c. A sticking impact conserves the angular momentum about the contact point,
L = I angle_dot + m r x_dot (clockwise), and leaves it rolling: x_dot+ = r L / (I + m r^2).
A sliding impact changes the linear momentum by the full Coulomb impulse: x_dot+ = x_dot-
- mu (1 + e) c sign(w-), and angle_dot+ = angle_dot- + r mu (1 + e) m c sign(w-) / I.
"""

import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import unforced_run_against

import lerax_like as ll
from lerax_like.analysis.modes_reference import modes_reference_step, reference_modes
from lerax_like.env import EnvState
from lerax_like.physics import DiskFloor

G, RADIUS, V0 = 9.81, 0.1, 2.0
DT, STEPS = 0.25, 4  # T = 1 s, past t* for every mu >= 0.1


def _disk(mu=0.3, **floor):
    floor = {"static_friction": 1.0, "kinetic_friction": mu} | floor
    return ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=DT, floor=DiskFloor(**floor))


def _launched(env, v0=V0):
    y = jnp.array([0.0, RADIUS, 0.0, v0, 0.0, 0.0])
    return EnvState(y=y, steps=jnp.zeros((), int))


def _run(env, state, steps=STEPS):
    u = jnp.zeros(1)
    infos = []
    for _ in range(steps):
        state, info = env.evolve(state, u)
        infos.append(info)
    return state, infos


_evolve = eqx.filter_jit(lambda env, state: env.evolve(state, jnp.zeros(1)))


@pytest.mark.slow
def test_launched_disk_skids_then_rolls_at_the_closed_form_time_and_speed():
    mu = 0.3
    env = _disk(mu)
    state = _launched(env)
    switch_times = []
    for k in range(STEPS):
        state, info = _evolve(env, state)
        assert bool(info["solver_ok"])
        if int(info["switches"]):
            switch_times.append(k * DT + float(info["first_switch_time"]))
    t_star = V0 / (3 * mu * G)
    assert len(switch_times) == 1
    assert abs(switch_times[0] - t_star) < 1e-9
    x, z, _, x_dot, z_dot, angle_dot = np.asarray(state.y)
    assert abs(x_dot - 2 * V0 / 3) < 1e-9
    assert x_dot == RADIUS * angle_dot  # rolling, exactly
    assert z == RADIUS and z_dot == 0.0  # the contact stayed closed, exactly
    assert abs(x - (V0**2 / (18 * mu * G) + 2 * V0 * STEPS * DT / 3)) < 1e-9


def _position(env, mu):
    env = eqx.tree_at(lambda e: e.floor.kinetic_friction, env, mu)
    # One compiled step in a scan (a Python loop compiles one copy of the segment loop per step).
    state, _ = jax.lax.scan(lambda state, _: (env.evolve(state, jnp.zeros(1))[0], None), _launched(env), None, length=STEPS)
    return state.y[0]


def _closed_form_slope(mu):
    return -(V0**2) / (18 * mu**2 * G)


@pytest.mark.slow
def test_gradient_of_position_with_respect_to_mu_matches_closed_form():
    env = _disk()
    slope = jax.jit(jax.grad(lambda mu: _position(env, mu)))(jnp.asarray(0.3))
    assert abs(float(slope) - _closed_form_slope(0.3)) < 1e-6


@pytest.mark.slow
def test_gradient_over_1024_disks_reverse_and_forward_mode():
    mus = jnp.linspace(0.1, 0.9, 1024)
    env = _disk()
    expected = _closed_form_slope(mus)
    reverse = jax.jit(jax.vmap(jax.grad(lambda mu: _position(env, mu))))(mus)
    np.testing.assert_allclose(reverse, expected, rtol=0, atol=1e-6)
    forward_env = ll.with_adjoint(env, "forward")
    forward = jax.jit(jax.vmap(jax.jacfwd(lambda mu: _position(forward_env, mu))))(mus)
    np.testing.assert_allclose(forward, expected, rtol=0, atol=1e-6)


def _dropped(x_dot, angle_dot, fall_speed):
    # Just above the floor, falling: the impact comes within the first step.
    height = RADIUS + 1e-3
    return EnvState(y=jnp.array([0.0, height, 0.0, x_dot, -fall_speed, angle_dot]), steps=jnp.zeros((), int))


@pytest.mark.parametrize("mu", [1.0, 0.05])
def test_first_impact_matches_sticking_and_sliding_closed_forms(mu):
    e = 0.5
    env = ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=1e-3, floor=DiskFloor(static_friction=1.0, kinetic_friction=mu, restitution=e))
    x_dot, angle_dot, fall_speed = 1.5, -4.0, 3.0
    state, info = _evolve(env, _dropped(x_dot, angle_dot, fall_speed))
    assert bool(info["solver_ok"]) and int(info["impacts"]) == 1
    t_impact = float(info["first_impact_time"])
    c = np.sqrt(fall_speed**2 + 2 * G * 1e-3)  # speed at the floor (free fall)
    assert abs(t_impact - (c - fall_speed) / G) < 1e-9
    mass, inertia = 1.0, 0.5 * RADIUS**2
    slip = x_dot - RADIUS * angle_dot
    stopping = mass * inertia / (inertia + mass * RADIUS**2) * abs(slip)
    if stopping <= mu * (1 + e) * mass * c:  # sticking impact
        momentum = inertia * angle_dot + mass * RADIUS * x_dot
        x_after = RADIUS * momentum / (inertia + mass * RADIUS**2)
        angle_after = x_after / RADIUS
        assert mu == 1.0
    else:  # sliding impact
        x_after = x_dot - mu * (1 + e) * c * np.sign(slip)
        angle_after = angle_dot + RADIUS * mu * (1 + e) * mass * c * np.sign(slip) / inertia
        assert mu == 0.05
    # After the impact the disk flies (rebound e c > min_rebound_speed): nothing horizontal acts.
    _, z, _, x_dot_now, z_dot_now, angle_dot_now = np.asarray(state.y)
    assert abs(x_dot_now - x_after) < 1e-9
    assert abs(angle_dot_now - angle_after) < 1e-9
    assert abs(z_dot_now - (e * c - G * (1e-3 - t_impact))) < 1e-9


def test_slow_rebound_closes_the_contact_and_rolls():
    env = ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=0.1, floor=DiskFloor(restitution=0.0, static_friction=1.0, kinetic_friction=1.0))
    state, info = _evolve(env, _dropped(1.0, 0.0, 1.0))
    assert bool(info["solver_ok"]) and int(info["impacts"]) == 1
    _, z, _, x_dot, z_dot, angle_dot = np.asarray(state.y)
    assert z == RADIUS and z_dot == 0.0
    assert x_dot == RADIUS * angle_dot
    # A sticking impact (mu large) about the contact point: x_dot+ = m r^2 x_dot- / (I + m r^2) = 2/3.
    assert abs(x_dot - 2.0 / 3.0) < 1e-9


def _disk_reference(y0, t_end, *, mu_s, mu_k, e, min_rebound, torque=0.0, inertia_factor=0.5):
    """The disk's hybrid solve with SciPy's DOP853 at rtol 1e-12, its own events and maps typed from
    the equations: flight (x'' = 0, z'' = -g, I angle'' = torque); in contact, slip
    (m x'' = -mu_k m g s, I angle'' = torque + r mu_k m g s) or roll (angle'' = torque / (I + m r^2));
    impacts by the closed forms of the module docstring."""
    from scipy.integrate import solve_ivp

    mass, inertia = 1.0, inertia_factor * RADIUS**2
    t, y = 0.0, np.array(y0, dtype=float)
    closed, s = False, 0.0

    def field(t, y):
        if not closed:
            return [y[3], y[4], y[5], 0.0, -G, torque / inertia]
        if s == 0:
            angular = torque / (inertia + mass * RADIUS**2)
            return [y[3], 0.0, y[5], RADIUS * angular, 0.0, angular]
        force = -mu_k * mass * G * s
        return [y[3], 0.0, y[5], force / mass, 0.0, (torque - RADIUS * force) / inertia]

    def lands(t, y):
        # Only a disk moving down lands: SciPy may report the gap's zero again at the start of
        # the flight that follows a rebound (it sits at zero there).
        return y[1] - RADIUS if not closed and y[4] < 0 else 1.0

    def slip_ends(t, y):
        return s * (y[3] - RADIUS * y[5]) if closed and s != 0 else 1.0

    for event in (lands, slip_ends):
        event.terminal, event.direction = True, -1
    while t < t_end:
        solution = solve_ivp(field, (t, t_end), y, method="DOP853", rtol=1e-12, atol=1e-12, events=(lands, slip_ends))
        t, y = solution.t[-1], solution.y[:, -1].copy()
        if len(solution.t_events[0]):
            c = -y[4]
            slip = y[3] - RADIUS * y[5]
            normal = (1 + e) * mass * c
            if mass * inertia / (inertia + mass * RADIUS**2) * abs(slip) <= mu_k * normal:
                momentum = inertia * y[5] + mass * RADIUS * y[3]
                y[3] = RADIUS * momentum / (inertia + mass * RADIUS**2)
                y[5] = y[3] / RADIUS
            else:
                y[3] -= mu_k * normal * np.sign(slip) / mass
                y[5] += RADIUS * mu_k * normal * np.sign(slip) / inertia
            y[4] = e * c
            if y[4] < min_rebound:
                closed, y[1], y[4] = True, RADIUS, 0.0
                slip = y[3] - RADIUS * y[5]
                s = 0.0 if abs(slip) < 1e-12 else float(np.sign(slip))
        elif len(solution.t_events[1]):
            s = 0.0  # zero torque: rolling needs no friction, so it holds
            y[3] = RADIUS * y[5]
        else:
            break
    return y


@pytest.mark.slow
def test_a_disk_thrown_with_backspin_bounces_skids_and_rolls_as_the_scipy_reference():
    import diffrax

    floor = {"static_friction": 0.15, "kinetic_friction": 0.1, "restitution": 0.5, "min_rebound_speed": 0.05}
    env = ll.make("RollingDisk",
        radius=RADIUS, gravity=G, dt=0.02, floor=DiskFloor(**floor), solver="dopri8",
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=100_000,
    )
    y0 = np.array([0.0, RADIUS + 0.2, 0.0, 1.0, 0.0, -30.0])
    reference = functools.partial(_disk_reference, mu_s=0.15, mu_k=0.1, e=0.5, min_rebound=0.05)
    state, impacts, switches = unforced_run_against(env, y0, reference)
    assert impacts >= 3 and switches >= 1
    # Thrown forward with enough backspin, it comes back: rolling towards -x at the end, at the speed
    # that conserves the angular momentum about the contact point through the sliding impacts and
    # the skid, (x_dot + k r angle_dot) / (1 + k) with k = 1/2.
    assert float(state.y[3]) == RADIUS * float(state.y[5])
    assert abs(float(state.y[3]) - (1.0 + 0.5 * RADIUS * -30.0) / 1.5) < 1e-9


@pytest.mark.slow
def test_the_studies_reference_agrees_with_the_reference_typed_from_the_equations():
    # The studies' SciPy reference (`lerax_like.analysis.modes_reference`) runs the package's own
    # modes, guards and resets; `_disk_reference` shares nothing with them but the equations.
    floor = {"static_friction": 0.15, "kinetic_friction": 0.1, "restitution": 0.5, "min_rebound_speed": 0.05}
    env = ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=0.02, floor=DiskFloor(**floor))
    y0 = np.array([0.0, RADIUS + 0.2, 0.0, 1.0, 0.0, -30.0])
    y, fired = y0, []
    for k in range(1, 101):
        step = modes_reference_step(reference_modes(env, (k - 1) * 0.02), y, np.zeros(1), 0.02)
        y, fired = step.y, fired + [which for _, which in step.events]
        if k % 25 == 0:
            expected = _disk_reference(y0, k * 0.02, mu_s=0.15, mu_k=0.1, e=0.5, min_rebound=0.05)
            np.testing.assert_allclose(y, expected, rtol=0, atol=1e-8, err_msg=f"t = {k * 0.02}")
    assert fired.count(0) >= 3 and fired.count(1) >= 1  # impacts (guard 0), then the skid's end (guard 1)


@pytest.mark.slow
def test_a_step_that_needs_more_events_than_its_budget_fails_and_keeps_its_state():
    # Two impacts within the step (a fast rebound, then a slow one that closes), a budget of one event.
    floor = DiskFloor(restitution=0.5, min_rebound_speed=0.05, max_events=1)
    env = ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=0.05, floor=floor)
    state = EnvState(y=jnp.array([0.0, RADIUS + 1e-4, 0.0, 0.0, -0.15, 0.0]), steps=jnp.zeros((), int))
    next_state, info = _evolve(env, state)
    assert not bool(info["solver_ok"])
    np.testing.assert_array_equal(np.asarray(next_state.y), np.asarray(state.y))
    roomy = eqx.tree_at(lambda e: e.floor, env, DiskFloor(restitution=0.5, min_rebound_speed=0.05, max_events=4))
    _, info = _evolve(roomy, state)
    assert bool(info["solver_ok"]) and int(info["impacts"]) == 2
