"""PlanarQuadrotor: the scene added with two files and one registry line.

Its vector field against Lagrange's equations of a rigid body in the plane derived with
SymPy (thrusts as generalised forces), and the main job and the gradient study run on it
with no change to either.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp

import lerax_like as ll
from lerax_like.physics.planar_quadrotor import PlanarQuadrotorDynamics


def _lagrangian_accelerations():
    """`(q, q_dot, u, parameters) -> q_ddot` from SymPy, independently of the package."""
    t = sp.symbols("t")
    m, l, inertia, g, u0, u1 = sp.symbols("m l I g u0 u1", positive=True)
    x, z, theta = (sp.Function(name)(t) for name in ("x", "z", "theta"))
    q = [x, z, theta]
    kinetic = m / 2 * (x.diff(t) ** 2 + z.diff(t) ** 2) + inertia / 2 * theta.diff(t) ** 2
    lagrangian = kinetic - m * g * z
    # Each rotor thrusts along the body's up axis (-sin theta, cos theta), at +-l along
    # the arm (cos theta, sin theta): virtual work gives the generalised forces.
    up = sp.Matrix([-sp.sin(theta), sp.cos(theta)])
    arm = sp.Matrix([sp.cos(theta), sp.sin(theta)])
    centre = sp.Matrix([x, z])
    forces = [0, 0, 0]
    for thrust, side in ((u0, -1), (u1, 1)):
        point = centre + side * l * arm
        for i, coordinate in enumerate(q):
            forces[i] += (thrust * up).dot(point.diff(coordinate))
    equations = [
        sp.diff(lagrangian.diff(c.diff(t)), t) - lagrangian.diff(c) - forces[i] for i, c in enumerate(q)
    ]
    second = [c.diff(t, 2) for c in q]
    solution = sp.solve(equations, second, dict=True)[0]
    symbols = sp.symbols("x z th xd zd thd")
    replace = {c.diff(t): s for c, s in zip(q, symbols[3:])}
    replace.update({c: s for c, s in zip(q, symbols[:3])})
    accelerations = [sp.simplify(solution[a].subs(replace)) for a in second]
    return sp.lambdify([symbols, (u0, u1), (m, l, inertia, g)], accelerations, "numpy")


def test_vector_field_matches_lagrange_and_the_issue_equations():
    accelerations = _lagrangian_accelerations()
    rng = np.random.default_rng(0)
    with jax.enable_x64(True):
        for _ in range(20):
            parameters = rng.uniform([0.2, 0.05, 1e-3, 1.0], [5.0, 1.0, 1.0, 20.0])
            m, l, inertia, g = parameters
            dynamics = PlanarQuadrotorDynamics(mass=m, arm_length=l, moment_of_inertia=inertia, gravity=g)
            y = rng.uniform(-3, 3, size=6)
            u = rng.uniform(0, 20, size=2)
            field = np.asarray(dynamics.vector_field(0.0, jnp.asarray(y), jnp.asarray(u)))
            expected = np.concatenate([y[3:], accelerations(y, u, parameters)])
            np.testing.assert_allclose(field, expected, rtol=1e-12, atol=1e-12)
            # The issue's own statement of the equations.
            thrust = u.sum()
            by_hand = [-thrust * np.sin(y[2]) / m, thrust * np.cos(y[2]) / m - g, l * (u[1] - u[0]) / inertia]
            np.testing.assert_allclose(field[3:], by_hand, rtol=1e-12, atol=1e-12)


def test_zero_action_hovers():
    with jax.enable_x64(True):
        env = ll.PlanarQuadrotor()
        state = ll.EnvState(y=jnp.zeros(6), steps=jnp.asarray(0))
        next_state, _, reward, terminated, info = env.advance(state, jnp.zeros(2), key=None)
        np.testing.assert_allclose(np.asarray(next_state.y), 0.0, atol=1e-15)
        assert float(reward) == 1.0 and not bool(terminated) and bool(info["solver_ok"])


@pytest.mark.slow
def test_the_main_job_and_the_gradient_study_take_it(tmp_path):
    from lerax_like.cli import main

    assert main(["study", "PlanarQuadrotor", "--quick", "--no-plot", "--no-progress", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "PlanarQuadrotor.csv").exists()
    assert main(["gradients", "PlanarQuadrotor", "--quick", "--no-plot", "--out", str(tmp_path)]) == 0
