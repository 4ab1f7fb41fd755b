"""Physics add-ons (joint damping, end stops) as generalised forces on carts and chains.

The reference is Lagrange's equations with generalised forces, derived by SymPy from the
rods' geometry: the joint dampers from Rayleigh's dissipation function
`D = b/2 sum_i (theta_i_dot - theta_{i-1}_dot)**2` (the cart or the ground being joint 1's
neighbour, with no angular rate), `Q = -dD/dq_dot`, and the end stops as the horizontal
force a one-sided spring-damper puts on the cart, written here from its description.
Then: energy and the springs' potential conserved without damping, energy falling
with it at the rate the dampers dissipate, and the plain `CartPoleDynamics` back to
Gymnasium's four parameters and equations.
"""

import functools

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import lerax_like as ll
from lerax_like.physics import (
    CartChainDynamics,
    CartPoleDynamics,
    EndStops,
    ForcedDynamics,
    JointDamping,
    NLinkPendulumDynamics,
)


# --- An independent reference: SymPy's Lagrangian with generalised forces ------------------


@functools.cache
def _lagrange_reference(n_links: int, cart: bool):
    """`(q, q_dot, masses, lengths, g, cart_mass, b, F, torques) -> (M, rhs)` with `M q'' = rhs`.

    Uniform rods of full length `l_i`, angles absolute from upright and positive towards
    `+x`. `F` is the horizontal force on the cart (input plus end stops), `torques` the
    joint inputs of a chain without a cart (`u_i` on rod i, `-u_i` on rod i-1), `b` the
    joint dampers' coefficient.
    """
    t = sp.symbols("t")
    masses = sp.symbols(f"m1:{n_links + 1}", positive=True)
    lengths = sp.symbols(f"l1:{n_links + 1}", positive=True)
    g, cart_mass, b, force = sp.symbols("g M b F")
    torques = sp.symbols(f"u1:{n_links + 1}")
    thetas = [sp.Function(f"theta{i + 1}")(t) for i in range(n_links)]
    x = sp.Function("x")(t) if cart else sp.Integer(0)
    coordinates = ([x] if cart else []) + thetas

    kinetic = cart_mass * x.diff(t) ** 2 / 2 if cart else sp.Integer(0)
    potential = sp.Integer(0)
    joint_x, joint_z = x, sp.Integer(0)
    for m, l, theta in zip(masses, lengths, thetas):
        centre_x, centre_z = joint_x + l / 2 * sp.sin(theta), joint_z + l / 2 * sp.cos(theta)
        kinetic += m * (centre_x.diff(t) ** 2 + centre_z.diff(t) ** 2) / 2 + m * l**2 / 24 * theta.diff(t) ** 2
        potential += m * g * centre_z
        joint_x, joint_z = joint_x + l * sp.sin(theta), joint_z + l * sp.cos(theta)
    lagrangian = kinetic - potential

    # Rayleigh's dissipation function of the joint dampers: joint 1 joins rod 1 to the
    # cart or the ground, neither of which rotates.
    rates = [theta.diff(t) for theta in thetas]
    relative_rates = [rates[0]] + [rates[i] - rates[i - 1] for i in range(1, n_links)]
    dissipation = b / 2 * sum(rate**2 for rate in relative_rates)
    # Virtual work of the inputs: F on x, or the joint torques on the relative angles.
    if cart:
        work = force * x
    else:
        relative_angles = [thetas[0]] + [thetas[i] - thetas[i - 1] for i in range(1, n_links)]
        work = sum(u * angle for u, angle in zip(torques, relative_angles))

    q = sp.symbols(f"q0:{len(coordinates)}")
    q_dot = sp.symbols(f"qd0:{len(coordinates)}")
    q_ddot = sp.symbols(f"qdd0:{len(coordinates)}")
    substitutions = {}
    for coordinate, a, v, p in zip(coordinates, q_ddot, q_dot, q):
        substitutions[coordinate.diff(t, 2)] = a
    for coordinate, v in zip(coordinates, q_dot):
        substitutions[coordinate.diff(t)] = v
    for coordinate, p in zip(coordinates, q):
        substitutions[coordinate] = p

    equations = []
    for coordinate in coordinates:
        generalised_force = work.diff(coordinate) - dissipation.diff(coordinate.diff(t))
        euler_lagrange = lagrangian.diff(coordinate.diff(t)).diff(t) - lagrangian.diff(coordinate)
        equations.append(sp.expand((euler_lagrange - generalised_force).subs(substitutions)))
    mass_matrix, rhs = sp.linear_eq_to_matrix(equations, q_ddot)
    arguments = (q, q_dot, masses, lengths, g, cart_mass, b, force, torques)
    return sp.lambdify(arguments, [mass_matrix, rhs], "numpy")


def _reference_accelerations(n_links, cart, q, q_dot, masses, lengths, g, cart_mass, b, force, torques):
    mass_matrix, rhs = _lagrange_reference(n_links, cart)(
        q, q_dot, masses, lengths, g, cart_mass, b, force, torques
    )
    return np.linalg.solve(np.asarray(mass_matrix, dtype=float), np.asarray(rhs, dtype=float).ravel())


def _stop_force(x, x_dot, stiffness, damping, limit):
    """The end stops from their description: past a stop by p, push back with max(k p + c p', 0)."""
    if x > limit:
        return -max(stiffness * (x - limit) + damping * x_dot, 0.0)
    if x < -limit:
        return max(stiffness * (-limit - x) - damping * x_dot, 0.0)
    return 0.0


def _random_add_ons(rng):
    damping, stiffness, stop_damping = rng.uniform(0.0, 300.0), rng.uniform(0.0, 1e6), rng.uniform(0.0, 1e3)
    return damping, stiffness, stop_damping, rng.uniform(0.5, 2.5)


_field = jax.jit(lambda dynamics, y, u: dynamics.vector_field(0.0, y, u))


def _relative(ours, reference):
    return float(np.max(np.abs(ours - reference)) / np.max(np.abs(reference)))


def test_cartpole_add_ons_match_lagrange_with_generalised_forces():
    rng = np.random.default_rng(0)
    errors = []
    for _ in range(40):
        cart_mass, pole_mass = rng.uniform(0.1, 3.0), rng.uniform(0.01, 2.0)
        half_length, gravity = rng.uniform(0.1, 2.0), rng.uniform(1.0, 20.0)
        damping, stiffness, stop_damping, limit = _random_add_ons(rng)
        # Many states in contact with one stop or the other, and moving into or out of it.
        x, x_dot = rng.uniform(-1.3, 1.3) * limit, 3 * rng.normal()
        theta, theta_dot, u = rng.uniform(-np.pi, np.pi), 3 * rng.normal(), 10 * rng.normal()
        dynamics = ForcedDynamics(
            CartPoleDynamics(gravity=gravity, cart_mass=cart_mass, pole_mass=pole_mass, half_length=half_length),
            (
                JointDamping(joint_damping=damping),
                EndStops(end_stop_stiffness=stiffness, end_stop_damping=stop_damping, track_limit=limit),
            ),
        )
        ours = np.asarray(_field(dynamics, jnp.array([x, x_dot, theta, theta_dot]), jnp.array([u])))
        force = u + _stop_force(x, x_dot, stiffness, stop_damping, limit)
        x_acc, theta_acc = _reference_accelerations(
            1, True, [x, theta], [x_dot, theta_dot], [pole_mass], [2 * half_length], gravity, cart_mass,
            damping, force, [0.0],
        )
        reference = np.array([x_dot, x_acc, theta_dot, theta_acc])
        errors.append(_relative(ours, reference))
    assert max(errors) < 1e-10, max(errors)


@pytest.mark.parametrize("cart", [True, False], ids=["double cart-pole", "double pendulum"])
def test_chain_add_ons_match_lagrange_with_generalised_forces(cart):
    rng = np.random.default_rng(1)
    n = 2
    errors = []
    for _ in range(40):
        masses, lengths = rng.uniform(0.05, 2.0, n), rng.uniform(0.2, 2.0, n)
        cart_mass, gravity = rng.uniform(0.1, 3.0), rng.uniform(1.0, 20.0)
        damping, stiffness, stop_damping, limit = _random_add_ons(rng)
        angles, rates = rng.uniform(-np.pi, np.pi, n), 3 * rng.normal(size=n)
        if cart:
            x, x_dot, u = rng.uniform(-1.3, 1.3) * limit, 3 * rng.normal(), rng.normal(size=1) * 10
            physics = CartChainDynamics(cart_mass=cart_mass, pole_masses=masses, pole_lengths=lengths, gravity=gravity)
            forces = (
                JointDamping(joint_damping=damping),
                EndStops(end_stop_stiffness=stiffness, end_stop_damping=stop_damping, track_limit=limit),
            )
            y = np.concatenate([[x], angles, [x_dot], rates])
            q, q_dot = np.concatenate([[x], angles]), np.concatenate([[x_dot], rates])
            force, torques = u[0] + _stop_force(x, x_dot, stiffness, stop_damping, limit), np.zeros(n)
        else:
            u = rng.normal(size=n) * 10
            physics = NLinkPendulumDynamics(masses=masses, lengths=lengths, gravity=gravity)
            forces = (JointDamping(joint_damping=damping),)
            y, q, q_dot = np.concatenate([angles, rates]), angles, rates
            force, torques = 0.0, u
        ours = np.asarray(_field(ForcedDynamics(physics, forces), jnp.asarray(y), jnp.asarray(u)))
        accelerations = _reference_accelerations(
            n, cart, q, q_dot, masses, lengths, gravity, cart_mass, damping, force, torques
        )
        errors.append(_relative(ours, np.concatenate([q_dot, accelerations])))
    assert max(errors) < 1e-10, max(errors)


# --- Energy: conserved with the springs' potential, dissipated by the dampers --------------


def _trajectory(dynamics, y0, t1):
    # Tsit5 rather than Dopri8: the stops' force has a kink at contact, past which a higher
    # order buys nothing (Dopri8 at the same tolerance drifts 4 times as much here).
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, args: dynamics.vector_field(t, y, jnp.zeros(1))),
        diffrax.Tsit5(),
        0.0,
        t1,
        None,
        jnp.asarray(y0),
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12),
        saveat=diffrax.SaveAt(ts=jnp.linspace(0.0, t1, 301)),
        max_steps=100_000,
    )
    return solution.ys


@pytest.mark.parametrize(
    "physics, y0",
    [
        (CartPoleDynamics(), [0.0, 1.5, 0.3, 0.0]),
        (CartChainDynamics(), [0.0, 0.3, -0.2, 1.5, 0.0, 0.0]),
    ],
    ids=["cart-pole", "double cart-pole"],
)
@pytest.mark.slow  # up to 2.8 s a case of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_undamped_end_stops_conserve_energy_with_their_potential(physics, y0):
    dynamics = ForcedDynamics(physics, (EndStops(end_stop_stiffness=1e4, track_limit=0.5),))
    ys = eqx.filter_jit(_trajectory)(dynamics, y0, 3.0)
    x = np.asarray(ys[:, 0])
    # The cart hits both stops (bounces back and forth) within the 3 s.
    assert x.max() > 0.5 and x.min() < -0.5
    total = np.asarray(jax.vmap(dynamics.energy)(ys))
    scale = np.max(np.abs(total))
    assert np.max(np.abs(total - total[0])) < 1e-9 * scale
    # Without the springs' potential the energy is not conserved through a contact.
    mechanical = np.asarray(jax.vmap(physics.energy)(ys))
    assert np.max(np.abs(mechanical - mechanical[0])) > 1e-2 * scale


_DAMPER = JointDamping(joint_damping=0.5)
_DAMPED_STOPS = EndStops(end_stop_stiffness=1e4, end_stop_damping=20.0, track_limit=0.5)


@pytest.mark.parametrize(
    "forces",
    [(_DAMPER,), (_DAMPED_STOPS,), (_DAMPER, _DAMPED_STOPS)],
    ids=["joint damping", "damped end stops", "both"],
)
@pytest.mark.parametrize(
    "physics, y0",
    [
        (CartPoleDynamics(), [0.0, 1.5, 0.3, 2.0]),
        (CartChainDynamics(), [0.0, 0.3, -0.2, 1.5, 2.0, -1.0]),
    ],
    ids=["cart-pole", "double cart-pole"],
)
def test_damping_makes_energy_fall(physics, y0, forces):
    dynamics = ForcedDynamics(physics, forces)
    assert not dynamics.conserves_energy
    ys = eqx.filter_jit(_trajectory)(dynamics, y0, 3.0)
    energy = np.asarray(jax.vmap(dynamics.energy)(ys))
    # Never rises (up to the solve's error), and falls by a visible amount overall.
    assert np.all(np.diff(energy) < 1e-9 * np.max(np.abs(energy)))
    assert energy[-1] < energy[0] - 1e-3 * np.max(np.abs(energy))


@pytest.mark.parametrize(
    "physics, size",
    [(CartPoleDynamics(), 4), (CartChainDynamics(), 6), (NLinkPendulumDynamics(), 6)],
    ids=["cart-pole", "double cart-pole", "3-link pendulum"],
)
def test_joint_dampers_dissipate_at_their_rate(physics, size):
    # Power balance with zero input: dE/dt = Q . q_dot = -b sum_i (theta_i' - theta_{i-1}')**2,
    # the rate at which the dampers turn energy into heat, at random states.
    b = 0.7
    dynamics = ForcedDynamics(physics, (JointDamping(joint_damping=b),))
    rng = np.random.default_rng(2)
    for _ in range(10):
        y = jnp.asarray(rng.normal(size=size))
        u = jnp.zeros(1 if physics.has_cart else physics.n_links)
        rate = jnp.vdot(jax.grad(dynamics.energy)(y), dynamics.vector_field(0.0, y, u))
        _, q_dot = physics.coordinates(np.asarray(y))
        angular = q_dot[1:] if physics.has_cart else q_dot
        relative = np.diff(np.concatenate([[0.0], angular]))
        expected = -b * np.sum(relative**2)
        assert float(rate) == pytest.approx(expected, rel=1e-10)


# --- The plain cart-pole: Gymnasium's four parameters and equations ------------------------


def test_cartpole_dynamics_is_gymnasiums_four_parameters():
    dynamics = CartPoleDynamics()
    assert len(jax.tree.leaves(eqx.filter(dynamics, eqx.is_array))) == 4
    y, u = jnp.array([0.1, -0.2, 0.3, 0.4]), jnp.array([1.0])
    equations = jax.make_jaxpr(dynamics.vector_field)(0.0, y, u).jaxpr.eqns
    assert len(equations) <= 40, len(equations)


@pytest.mark.parametrize("scene", [ll.CartPole, ll.CartPoleContinuous])
def test_a_scene_without_add_ons_integrates_gymnasiums_four_leaves(scene):
    plain = scene()
    assert len(jax.tree.leaves(eqx.filter(plain.physics, eqx.is_array))) == 4
    y, u = jnp.array([0.1, -0.2, 0.3, 0.4]), jnp.array([1.0])
    assert len(jax.make_jaxpr(plain.physics.vector_field)(0.0, y, u).jaxpr.eqns) <= 40
    # With add-on keywords the scene integrates the forced dynamics, add-ons included.
    rig = ll.make(scene, joint_damping=1.0, end_stop_stiffness=1e5, track_limit=2.0)
    assert isinstance(rig.physics, ForcedDynamics)
    assert [type(force) for force in rig.physics.forces] == [JointDamping, EndStops]
    assert float(rig.physics.forces[1].track_limit) == 2.0


def test_add_ons_at_zero_leave_the_vector_field_bitwise():
    # A zero force and a zero torque add exact zeros to Gymnasium's arithmetic.
    plain = CartPoleDynamics()
    idle = ForcedDynamics(plain, (JointDamping(joint_damping=0.0), EndStops()))
    ys = jax.random.uniform(jax.random.key(0), (64, 4), minval=-2.0, maxval=2.0)
    forces = jnp.where(jnp.arange(64) % 2 == 0, 10.0, -10.0)[:, None]
    ours = jax.vmap(lambda y, u: idle.vector_field(0.0, y, u))(ys, forces)
    base = jax.vmap(lambda y, u: plain.vector_field(0.0, y, u))(ys, forces)
    np.testing.assert_array_equal(np.asarray(ours), np.asarray(base))


# --- Construction: bad values and impossible compositions are refused by name ---------------


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: JointDamping(joint_damping=-1.0), r"joint_damping must be finite and >= 0 \(allowed range \[0, inf\)\)"),
        (lambda: JointDamping(joint_damping=float("inf")), "joint_damping must be finite"),
        (lambda: EndStops(end_stop_stiffness=-1.0), r"end_stop_stiffness .*\[0, inf\)"),
        (lambda: EndStops(end_stop_damping=float("nan")), r"end_stop_damping .*\[0, inf\)"),
        (lambda: EndStops(track_limit=0.0), r"track_limit must be > 0 \(allowed range \(0, inf\]\)"),
        (lambda: EndStops(track_limit=-2.0), "track_limit"),
        (lambda: ForcedDynamics(NLinkPendulumDynamics(), (EndStops(),)), "EndStops.*NLinkPendulumDynamics.*no cart"),
        (lambda: JointDamping(joint_damping=1.0).check(ll.PendulumDynamics()), "JointDamping.*PendulumDynamics"),
        (lambda: ForcedDynamics(ll.PendulumDynamics(), ()), "ForcedDynamics.*PendulumDynamics"),
    ],
)
def test_add_ons_refuse_bad_values_by_name(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_add_ons_accept_infinite_track_and_traced_values():
    assert float(EndStops(track_limit=float("inf")).track_limit) == np.inf
    # Built under vmap the values are tracers: let through, batched leaves come out.
    stops = eqx.filter_vmap(lambda k: EndStops(end_stop_stiffness=k))(jnp.array([1.0, 2.0]))
    assert stops.end_stop_stiffness.shape == (2,)
    damped = eqx.filter_vmap(lambda b: ForcedDynamics(CartPoleDynamics(), (JointDamping(joint_damping=b),)))(
        jnp.array([0.0, 1.0])
    )
    assert damped.forces[0].joint_damping.shape == (2,)
    assert ForcedDynamics(CartPoleDynamics(), (EndStops(),)).velocity_indices == (1, 3)
