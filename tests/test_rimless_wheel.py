"""The rimless wheel: its stance dynamics, impact map and limit cycle, derived independently.

SymPy derives the stance equation from the Lagrangian, the impact map from the angular
momentum about the new contact point, and the limit cycle's speed from the energy balance
over one step; SciPy's `solve_ivp` with located events (restarted at each impact, 1e-12)
integrates the passive wheel onto that cycle.
"""

import functools

import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

from lerax_like.analysis.hybrid_reference import Contact, hybrid_reference
from lerax_like.physics.rimless_wheel import RimlessWheelDynamics


PARAMETERS = [
    {},
    {"leg_length": 0.7, "spoke_half_angle": np.pi / 6, "slope": 0.3, "gravity": 9.81, "mass": 2.0},
    {"leg_length": 1.3, "spoke_half_angle": np.pi / 10, "slope": 0.05, "gravity": 3.7, "mass": 0.5},
]


def _symbols():
    return sp.symbols("theta theta_dot l alpha gamma g m", real=True)


def _values(dynamics):
    return {name: float(getattr(dynamics, name)) for name in ("leg_length", "spoke_half_angle", "slope", "gravity", "mass")}


@pytest.mark.parametrize("parameters", PARAMETERS)
def test_stance_dynamics_are_the_euler_lagrange_equation(parameters):
    theta, theta_dot, l, alpha, gamma, g, m = _symbols()
    t = sp.symbols("t")
    q = sp.Function("q")(t)
    torque = sp.symbols("tau", real=True)
    # The hub (a point mass) at l (sin q, cos q) from the stance foot, in the vertical plane.
    hub = sp.Matrix([l * sp.sin(q), l * sp.cos(q)])
    velocity = hub.diff(t)
    lagrangian = m * velocity.dot(velocity) / 2 - m * g * hub[1]
    equation = sp.diff(lagrangian.diff(q.diff(t)), t) - lagrangian.diff(q) - torque
    acceleration = sp.solve(equation, q.diff(t, 2))[0]
    acceleration = acceleration.subs(q.diff(t), theta_dot).subs(q, theta)

    dynamics = RimlessWheelDynamics(**parameters)
    values = _values(dynamics)
    rng = np.random.default_rng(0)
    for _ in range(5):
        y = rng.uniform(-1, 1, 2)
        u = rng.uniform(-2, 2, 1)
        expected = float(acceleration.subs({
            theta: y[0], theta_dot: y[1], torque: u[0], l: values["leg_length"], g: values["gravity"], m: values["mass"],
        }))
        got = dynamics.vector_field(0.0, jnp.asarray(y), jnp.asarray(u))
        np.testing.assert_allclose(np.asarray(got), [y[1], expected], rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("parameters", PARAMETERS)
def test_heel_strike_conserves_angular_momentum_about_the_new_foot(parameters):
    theta, theta_dot, l, alpha, gamma, g, m = _symbols()
    theta_after, rate_after = sp.symbols("theta_after rate_after", real=True)
    # Before: stance foot at the origin, hub at l (sin theta, cos theta), moving at l theta_dot
    # perpendicular to the stance spoke. The front spoke points from the hub at angle theta - 2 alpha.
    hub = sp.Matrix([l * sp.sin(theta), l * sp.cos(theta)])
    velocity = sp.Matrix([l * sp.cos(theta), -l * sp.sin(theta)]) * theta_dot
    front_foot = hub - l * sp.Matrix([sp.sin(theta - 2 * alpha), sp.cos(theta - 2 * alpha)])
    arm = hub - front_foot
    momentum_before = m * (arm[0] * velocity[1] - arm[1] * velocity[0])
    # After: the front foot is the pivot, the hub at angle theta_after from the vertical.
    arm_after = l * sp.Matrix([sp.sin(theta_after), sp.cos(theta_after)])
    velocity_after = sp.Matrix([l * sp.cos(theta_after), -l * sp.sin(theta_after)]) * rate_after
    momentum_after = m * (arm_after[0] * velocity_after[1] - arm_after[1] * velocity_after[0])
    # The hub does not move in the impact: its angle from the new foot is theta - 2 alpha.
    rate = sp.solve(sp.Eq(momentum_before, momentum_after.subs(theta_after, theta - 2 * alpha)), rate_after)[0]
    assert sp.simplify(rate - sp.cos(2 * alpha) * theta_dot) == 0

    dynamics = RimlessWheelDynamics(**parameters)
    values = _values(dynamics)
    y = jnp.asarray([values["slope"] + values["spoke_half_angle"], 1.3])
    got = np.asarray(dynamics.heel_strike(y))
    expected_rate = float(rate.subs({theta: float(y[0]), theta_dot: 1.3, alpha: values["spoke_half_angle"], l: 1, m: 1}))
    np.testing.assert_allclose(got, [values["slope"] - values["spoke_half_angle"], expected_rate], rtol=1e-14, atol=1e-15)
    # The new foot is on the slope: the hub's height above the slope from either foot agrees.
    front_gap_after = dynamics.front_gap(jnp.asarray(got))
    np.testing.assert_allclose(float(front_gap_after), 2 * values["spoke_half_angle"], rtol=1e-14)


@functools.cache
def _limit_cycle_from_energy_balance():
    """The fixed point of the step map, derived from the geometry of one step."""
    _, _, l, alpha, gamma, g, _ = _symbols()
    speed_squared = sp.symbols("omega_squared", positive=True)
    # Hub height above the foot: l cos(theta); a step runs from gamma - alpha to gamma + alpha.
    drop = l * sp.cos(gamma - alpha) - l * sp.cos(gamma + alpha)
    before_impact_squared = speed_squared + 2 * g * drop / l**2
    (fixed_point,) = sp.solve(sp.Eq(speed_squared, sp.cos(2 * alpha) ** 2 * before_impact_squared), speed_squared)
    return sp.sqrt(fixed_point), (l, alpha, gamma, g)


@pytest.mark.parametrize("parameters", PARAMETERS)
def test_limit_cycle_speed_is_the_fixed_point_of_the_energy_balance(parameters):
    fixed_point, (l, alpha, gamma, g) = _limit_cycle_from_energy_balance()
    dynamics = RimlessWheelDynamics(**parameters)
    values = _values(dynamics)
    expected = float(sp.N(fixed_point.subs({
        l: values["leg_length"], alpha: values["spoke_half_angle"], gamma: values["slope"], g: values["gravity"],
    }), 30))
    assert abs(float(dynamics.limit_cycle_speed) - expected) < 1e-12 * expected
    assert bool(dynamics.rolls_over_the_top)


@pytest.mark.parametrize("start_speed", [0.99, 1.5, 2.5, 4.0])
def test_passive_wheel_settles_on_the_limit_cycle(start_speed):
    dynamics = RimlessWheelDynamics()
    contacts = [Contact(dynamics.front_gap, dynamics.heel_strike), Contact(dynamics.rear_gap, dynamics.rear_strike)]
    # Started just after a heel strike, fast enough to pass over the top.
    start = np.array([float(dynamics.slope - dynamics.spoke_half_angle), start_speed])
    assert start_speed > float(dynamics.speed_to_pass_the_top)
    solution = hybrid_reference(dynamics.vector_field, contacts, start, np.zeros(1), 60.0, rtol=1e-13, atol=1e-13)
    assert np.all(solution.event_contacts == 0)  # heel strikes only: it rolls on
    after_impacts = np.array([segment.y[1, 0] for segment in solution.segments[1:]])
    # The step map contracts by cos(2 alpha)**2 = 1/2 per step: 40 steps are within 1e-12.
    assert len(after_impacts) > 40
    assert abs(after_impacts[-1] - float(dynamics.limit_cycle_speed)) < 1e-9
    # Monotone approach, as a one-dimensional contraction with positive slope gives.
    distance = np.abs(after_impacts - float(dynamics.limit_cycle_speed))
    assert np.all(np.diff(distance[:20]) < 0)


def test_slow_wheel_rocks_back_onto_its_rear_spoke():
    dynamics = RimlessWheelDynamics()
    contacts = [Contact(dynamics.front_gap, dynamics.heel_strike), Contact(dynamics.rear_gap, dynamics.rear_strike)]
    start = np.array([float(dynamics.slope - dynamics.spoke_half_angle), 0.5])
    assert 0.5 < float(dynamics.speed_to_pass_the_top)
    solution = hybrid_reference(dynamics.vector_field, contacts, start, np.zeros(1), 0.5)
    # It climbs, falls back and lands on the rear spoke, at -cos(2 alpha) of the speed it started with.
    assert solution.event_contacts[0] == 1
    after = solution.segments[1].y[:, 0]
    np.testing.assert_allclose(after[1], -np.cos(2 * float(dynamics.spoke_half_angle)) * 0.5, rtol=1e-10)


@pytest.mark.slow
def test_the_scene_rolls_onto_the_closed_form_limit_cycle():
    # The env's own hybrid step (heel strikes located by lerax_like.hybrid), zero torque,
    # from starts that pass over the top; the post-impact speed of the last strike is read
    # off the end state of its env step by the stance's energy (conserved between strikes).
    import diffrax
    import jax

    import lerax_like as ll

    env = ll.make("RimlessWheel", solver="dopri8", stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
                          max_steps=100_000)
    wheel = env.dynamics
    after_strike = float(wheel.slope - wheel.spoke_half_angle)
    starts = jnp.asarray([[after_strike, 1.02 * float(wheel.speed_to_pass_the_top)], [0.3, 3.5]])

    def run(y0):
        def body(state, _):
            state, info = env.evolve(state, jnp.zeros(1))
            return state, (state.y, info["impacts"], info["solver_ok"])

        return jax.lax.scan(body, ll.EnvState(y=y0, steps=jnp.asarray(0)), None, length=900)[1]

    ys, impacts, ok = (np.asarray(a) for a in jax.jit(jax.vmap(run))(starts))
    assert ok.all()
    g_over_l = float(wheel.gravity / wheel.leg_length)
    for y, count in zip(ys, impacts):
        assert count.sum() > 40 and count.max() == 1
        last = y[np.flatnonzero(count)[-1]]
        speed = np.sqrt(last[1] ** 2 + 2 * g_over_l * (np.cos(last[0]) - np.cos(after_strike)))
        assert abs(speed - float(wheel.limit_cycle_speed)) < 1e-9


@pytest.mark.slow  # 3.4 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_hybrid_reference_trajectories_of_a_dropped_ball_match_the_closed_form():
    # The study's event-restarted SciPy reference, on an env's own contacts: a ball dropped
    # from rest at height h lands at t* = sqrt(2 h / g) and leaves at e g t*.
    import lerax_like as ll
    from lerax_like.analysis.hybrid_reference import hybrid_reference_trajectories

    env = ll.make("BouncingBall", dt=0.5, restitution=0.8)
    g, h, e = float(env.dynamics.gravity), 1.0, 0.8
    states, inside = hybrid_reference_trajectories(
        env, np.array([[0.0, h, 0.0, 0.0]]), np.zeros((1, 2)), 0.5, np.array([0.25]), rtol=1e-13, atol=1e-13
    )
    landing = np.sqrt(2 * h / g)
    after = 0.5 - landing
    rebound = e * g * landing
    np.testing.assert_allclose(states[0, 0], [0.0, rebound * after - g / 2 * after**2, 0.0, rebound - g * after],
                               rtol=0, atol=1e-11)
    # A quarter of the step, 0.125 s, before the landing.
    np.testing.assert_allclose(inside[0, 0, 0], [0.0, h - g / 2 * 0.125**2, 0.0, -g * 0.125], rtol=0, atol=1e-11)
