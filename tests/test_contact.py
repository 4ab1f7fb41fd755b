"""Impacts located as events (`lerax_like.hybrid`), checked against closed forms and conservation.

- A ball's impact times against `t* = (v0 + sqrt(v0^2 + 2 g h)) / g` and the bounces after it,
  its energy after k bounces against `e^(2k)` times the initial one;
- a trajectory that touches the wall within one adaptive step (found, and missed without the
  grazing guard);
- a ball dropped to rest: a bounded event count equal to what the rebound rule predicts,
  `solver_ok`, a finite state and finite gradients; a step that runs out of events fails;
- the impulse map on a cart-pole against the conservation laws of an impact with a wall.
"""

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like._segments import integrate_hybrid
from lerax_like.physics.contact import mass_matrix, with_coordinates


GRAVITY = 9.81


def _ball(**keywords):
    return ll.make("BouncingBall", **{"restitution": 0.8, **keywords})


def _state(y):
    return ll.EnvState(y=jnp.asarray(y, dtype=jnp.float64), steps=jnp.zeros((), dtype=int))


def _impact_times(env, y0, steps, u):
    """The impact times and the states after each env step, with `u` held."""
    step = jax.jit(lambda state: env.evolve(state, u))
    state, times, states = _state(y0), [], []
    for k in range(steps):
        state, info = step(state)
        assert bool(info["solver_ok"])
        assert int(info["impacts"]) <= 1, "one impact per env step in this test"
        if int(info["impacts"]) == 1:
            times.append(k * float(env.dt) + float(info["first_impact_time"]))
        states.append(np.asarray(state.y))
    return np.array(times), np.array(states)


@pytest.mark.slow
@pytest.mark.parametrize("v0", [0.0, 2.0])
def test_ball_impact_times_match_the_closed_form(v0):
    h, e = 1.0, 0.8
    env = _ball(restitution=e, dt=0.1, solver="tsit5")
    times, _ = _impact_times(env, [0.0, h, 0.0, v0], 30, jnp.zeros(2))
    first = (v0 + math.sqrt(v0**2 + 2 * GRAVITY * h)) / GRAVITY
    speed = math.sqrt(v0**2 + 2 * GRAVITY * h)
    # After bounce j the ball leaves at e^j times the first impact speed and flies 2 v / g.
    expected = first + np.concatenate([[0.0], np.cumsum([2 * e**j * speed / GRAVITY for j in range(1, len(times))])])
    assert len(times) >= 3
    np.testing.assert_allclose(times, expected, rtol=0, atol=1e-12)


@pytest.mark.slow
def test_vertical_drop_energy_after_k_bounces_is_e_to_the_2k():
    h, e = 1.0, 0.7
    env = _ball(restitution=e, dt=0.05, solver="tsit5")
    step = jax.jit(lambda state: env.evolve(state, jnp.zeros(2)))
    state = _state([0.0, h, 0.0, 0.0])
    initial = float(env.dynamics.energy(state.y))
    bounces, checked = 0, 0
    for _ in range(40):
        state, info = step(state)
        assert bool(info["solver_ok"])
        bounces += int(info["impacts"])
        if bounces and int(info["impacts"]) == 0:
            energy = float(env.dynamics.energy(state.y))
            assert abs(energy / initial - e ** (2 * bounces)) <= 1e-10, (bounces, energy / initial)
            checked += 1
    assert bounces >= 3 and checked >= 10


def _grazing(guarded: bool):
    """A ball held at constant height, sent at the wall and pushed back: it reaches 1 mm past it."""
    env = _ball(restitution=0.5, dt=0.5, solver="tsit5")
    push, penetration, wall = 20.0, 1e-3, float(env.contacts[0].wall_position)
    speed = math.sqrt(2 * push * (0.5 + penetration))  # x(t) = vt - a t^2 / 2 peaks 1 mm past the wall
    u = jnp.array([-push, GRAVITY])  # the vertical thrust cancels gravity
    integrator = env.integrator
    if not guarded:
        # Any controller but the plain PIDController goes unguarded; this one steps as it does.
        class Unguarded(diffrax.PIDController):
            pass

        integrator = ll.Integrator(integrator.solver, Unguarded(rtol=1e-6, atol=1e-9))
    y0 = jnp.array([wall - 0.5, 1.0, speed, 0.0])
    y, info = jax.jit(
        lambda y0: integrate_hybrid(integrator, env.modes(), y0, u, env.dt, velocity_indices=env.physics.velocity_indices)
    )(y0)
    contact_time = (speed - math.sqrt(speed**2 - 2 * push * 0.5)) / push
    return y, info, contact_time, speed, push


@pytest.mark.slow
def test_a_grazing_contact_within_one_adaptive_step_is_found():
    y, info, contact_time, speed, push = _grazing(guarded=True)
    assert bool(info["solver_ok"]) and int(info["impacts"]) == 1
    np.testing.assert_allclose(float(info["first_impact_time"]), contact_time, rtol=0, atol=1e-12)
    # After the impact the ball leaves at half its normal speed, then decelerates at `push`.
    normal = speed - push * contact_time
    tau = 0.5 - contact_time
    expected_x = 1.0 - 0.5 * normal * tau - 0.5 * push * tau**2
    np.testing.assert_allclose(float(y[0]), expected_x, rtol=0, atol=1e-10)
    # Without the guard the same trajectory is one adaptive step over the touch: the step
    # ends on the near side of the wall and no sign change shows.
    _, unguarded, _, _, _ = _grazing(guarded=False)
    assert int(unguarded["impacts"]) == 0


def _drop_to_rest(env, steps):
    def run(y0):
        state = _state(y0)

        def body(state, _):
            state, info = env.evolve(state, jnp.zeros(2))
            return state, (info["impacts"], info["solver_ok"])

        return jax.lax.scan(body, state, None, length=steps)

    return run


@pytest.mark.slow
def test_a_ball_dropped_to_rest_stops_after_the_bounces_the_rule_predicts():
    h, e, rebound = 1.0, 0.5, 1e-2
    env = _ball(restitution=e, min_rebound_speed=rebound, dt=0.05)
    state, (impacts, ok) = jax.jit(_drop_to_rest(env, 40))(jnp.array([0.0, h, 0.0, 0.0]))
    # Rule: impact k leaves at e^k v; the first rebound slower than min_rebound_speed is plastic.
    speed = math.sqrt(2 * GRAVITY * h)
    expected = next(k for k in range(1, 100) if e**k * speed < rebound)
    assert int(jnp.sum(impacts)) == expected
    assert bool(jnp.all(ok))  # coming to rest within the event budget is no failure
    assert int(jnp.max(impacts)) <= env.contacts[0].max_events
    y = np.asarray(state.y)
    assert np.all(np.isfinite(y))
    assert abs(y[1]) < 1e-12 and y[3] == 0.0  # resting on the floor, at rest
    # Gradients of the resting height and of the path's energy are finite.
    grad = jax.jit(jax.grad(lambda y0: jnp.sum(_drop_to_rest(env, 40)(y0)[0].y ** 2)))(jnp.array([0.0, h, 0.0, 0.0]))
    assert np.all(np.isfinite(np.asarray(grad)))


@pytest.mark.slow
def test_a_step_that_runs_out_of_events_fails_and_is_reported():
    # With no rest rule to speak of, a ball's bounces pile up without end (Zeno) and
    # exhaust any budget: the step fails, keeps its pre-step state and says so.
    env = _ball(restitution=0.5, min_rebound_speed=1e-14, max_events=4, dt=0.02)
    state = _state([0.0, 1e-4, 0.0, 0.0])
    next_state, _, reward, terminated, info = eqx.filter_jit(env.advance)(state, jnp.zeros(2), key=None)
    assert not bool(info["solver_ok"]) and bool(terminated)
    np.testing.assert_array_equal(np.asarray(next_state.y), np.asarray(state.y))
    assert float(reward) == float(env.worst_reward)


def test_the_cart_wall_impact_is_impulse_consistent():
    # A cart-pole hitting a wall: the wall's impulse acts on x only, so the pole's angular
    # momentum about the hinge... is not conserved, but the generalised momentum conjugate
    # to theta is (no impulse on theta), the cart rebounds at e times its speed, and the
    # energy lost is the kinetic energy of the normal speed: (1 - e^2) v^2 / (2 J M^-1 J^T).
    e = 0.6
    env = ll.make("CartPoleContinuous",
        track_limit=0.5, restitution=e, x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, solver="tsit5"
    )
    walls = env.contacts[0]
    before = jnp.array([0.5, 1.3, 0.4, -0.7])
    after, m_before, m_after = jax.jit(
        lambda y: (walls.impact(env.dynamics, y, 1), mass_matrix(env.dynamics, y),
                   mass_matrix(env.dynamics, walls.impact(env.dynamics, y, 1)))
    )(before)
    p_before = m_before @ before[1::2]
    p_after = m_after @ after[1::2]
    np.testing.assert_allclose(float(p_after[1]), float(p_before[1]), rtol=1e-13)
    np.testing.assert_allclose(float(after[1]), -e * 1.3, rtol=1e-13)
    assert float(after[3]) != float(before[3])  # the pole's rate jumps too
    effective_mass = 1.0 / float(jnp.linalg.inv(m_before)[0, 0])
    lost = float(env.dynamics.energy(before) - env.dynamics.energy(after))
    np.testing.assert_allclose(lost, (1 - e**2) * effective_mass * 1.3**2 / 2, rtol=1e-12)


@pytest.mark.slow  # 4.7 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_walls_and_end_stops_are_chosen_by_keyword_also_through_gymnasium():
    import gymnasium

    walled = ll.make("CartPoleContinuous", track_limit=0.5, restitution=0.8)
    assert walled.forces == () and isinstance(walled.contacts[0], ll.physics.contact.Walls)
    assert float(walled.contacts[0].track_limit) == 0.5
    stopped = ll.make("CartPoleContinuous", track_limit=0.5, end_stop_stiffness=1e5)
    assert stopped.contacts == () and isinstance(stopped.forces[0], ll.EndStops)
    with pytest.raises(ValueError, match="EndStops .* or Walls"):
        ll.make("CartPole", restitution=0.5, end_stop_stiffness=1e5)
    with pytest.raises(ValueError, match="restitution"):
        ll.make("CartPole", restitution=1.5)
    env = gymnasium.make("lerax_like/CartPole-v1", track_limit=0.5, restitution=0.8)
    assert isinstance(env.unwrapped.scene.contacts[0], ll.physics.contact.Walls)
    env.close()


def test_backsolve_is_refused_by_name():
    env = ll.with_adjoint(_ball(), "backsolve")
    with pytest.raises(ValueError, match="BacksolveAdjoint"):
        env.evolve(_state([0.0, 1.0, 0.0, 0.0]), jnp.zeros(2))


@pytest.mark.slow
def test_forward_mode_through_an_impact_equals_reverse_mode():
    env = _ball(dt=0.5)
    forward = ll.with_adjoint(env, "forward")
    y0 = jnp.array([0.0, 1.0, 0.3, 0.0])
    reverse_jacobian = jax.jit(jax.jacrev(lambda y: env.evolve(_state(y), jnp.zeros(2))[0].y))(y0)
    forward_jacobian = jax.jit(jax.jacfwd(lambda y: forward.evolve(_state(y), jnp.zeros(2))[0].y))(y0)
    assert int(env.evolve(_state(y0), jnp.zeros(2))[1]["impacts"]) == 1
    np.testing.assert_allclose(np.asarray(forward_jacobian), np.asarray(reverse_jacobian), rtol=1e-10, atol=1e-12)
    # The height's sensitivity to the initial height after one bounce, in closed form: the
    # impact time t* = sqrt(2 h / g) and the rebound speed e g t* give
    # z(T) = e g t* (T - t*) - g (T - t*)^2 / 2, differentiated in h.
    e, h, T = 0.8, 1.0, 0.5
    t_star = math.sqrt(2 * h / GRAVITY)
    dt_dh = 1 / (GRAVITY * t_star)
    dz_dh = (e * GRAVITY * (T - t_star) - e * GRAVITY * t_star + GRAVITY * (T - t_star)) * dt_dh
    np.testing.assert_allclose(float(forward_jacobian[1, 1]), dz_dh, rtol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["CartPole", "CartPoleContinuous"])
def test_semi_implicit_euler_pushed_into_a_wall_comes_to_rest_without_failing(scene):
    # Two traps of a fixed-step solver at a wall, both measured on these starts before the Zeno
    # rule (`hybrid.ZENO_FRACTION`): semi-implicit Euler's dense output blends the velocities
    # while the positions move with the new ones, so a located crossing could read a state
    # moving away (no impact) and the next step cross again at once; and pushed into the wall
    # it settles on impacts at h a / (1 + e), above any rebound threshold. Each ran out of
    # events on CartPoleContinuous (`solver_ok` False from the 7th step; from the 10th with the
    # first trap alone removed); now the cart comes to rest.
    env = ll.make(
        scene, solver="semi_implicit_euler", restitution=0.8, track_limit=0.06, x_threshold=jnp.inf, theta_threshold_radians=jnp.inf
    )
    states = jax.vmap(lambda key: env.reset(key=key)[0])(jax.random.split(jax.random.key(1), 4))
    push = jnp.asarray(1) if env.action_space.shape == () else jnp.ones(env.action_space.shape)
    actions = jnp.broadcast_to(push, (4, 12, *jnp.shape(push)))
    ys, info = jax.jit(jax.vmap(lambda state, acts: ll.rollout(env, state, acts)))(states, actions)
    assert bool(jnp.all(info["solver_ok"])), np.asarray(info["solver_ok"])
    assert int(jnp.sum(info["impacts"])) >= 4  # every cart reached the wall
    assert float(jnp.max(ys[..., 0])) <= 0.06 + 1e-12  # and none passed it



@pytest.mark.parametrize(
    ("dynamics", "size"), [(ll.physics.BallDynamics(mass=1.3), 4), (ll.physics.SlidingBlockDynamics(mass=0.7, incline=0.2), 2)],
    ids=["Ball", "SlidingBlock"],
)
def test_a_point_mass_s_closed_form_mass_matrix_is_its_energy_s_hessian(dynamics, size):
    # Impacts and contact forces read M from the closed form; the Hessian of a point mass's
    # energy in its velocities is its mass, exactly.
    for y in np.random.default_rng(4).normal(size=(3, size)):
        y = jnp.asarray(y)
        _, q_dot = dynamics.coordinates(y)
        hessian = jax.hessian(lambda v: dynamics.energy(with_coordinates(dynamics, y, velocities=v)))(q_dot)
        np.testing.assert_array_equal(np.asarray(mass_matrix(dynamics, y)), np.asarray(hessian))
        assert mass_matrix(dynamics, y).dtype == hessian.dtype


@pytest.mark.slow  # 2.1 to 7.1 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
@pytest.mark.parametrize(
    ("dynamics", "size"),
    [
        (ll.CartPoleDynamics(pole_mass=0.3, half_length=0.7, cart_mass=1.4), 4),
        (ll.CartChainDynamics(pole_masses=(0.1, 0.2), pole_lengths=(0.5, 0.8)), 6),
        (ll.NLinkPendulumDynamics(masses=[1.0, 0.5, 2.0], lengths=[0.3, 1.0, 0.6]), 6),
    ],
    ids=["CartPole", "CartChain", "NLinkPendulum"],
)
def test_a_chains_closed_form_mass_matrix_and_potential_are_its_energy_s(dynamics, size):
    # Impacts read M(q) from a chain's own closed form (`mass_matrix(y)`); the impulse map is
    # consistent with the energy only if it is the Hessian of that energy in the velocities.
    for y in np.random.default_rng(3).normal(size=(5, size)):
        y = jnp.asarray(y)
        _, q_dot = dynamics.coordinates(y)
        hessian = jax.hessian(lambda v: dynamics.energy(with_coordinates(dynamics, y, velocities=v)))(q_dot)
        assert isinstance(dynamics, ll.physics.AbstractChainDynamics) and hasattr(dynamics, "mass_matrix")
        np.testing.assert_allclose(np.asarray(mass_matrix(dynamics, y)), np.asarray(hessian), rtol=4 * np.finfo(float).eps, atol=0)
        # And its potential energy (which cart friction's normal force differentiates) is the
        # energy at rest.
        at_rest = with_coordinates(dynamics, y, velocities=jnp.zeros_like(q_dot))
        assert float(dynamics.potential_energy(y)) == float(dynamics.energy(at_rest))
