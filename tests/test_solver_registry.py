"""The registry of solver presets: declared orders and stages checked against the methods."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.cli import solver_from_spec
from lerax_like.integrate import SOLVERS, describe_solver


def _rotation(t, y, args):
    # y' = (1 + |y|^2) J y: a nonlinear rotation whose speed depends on the (conserved)
    # radius, so y(t) = R((1 + r0^2) t) y0 exactly.
    del t, args
    x, v = y
    return (1.0 + x**2 + v**2) * jnp.stack([-v, x])


def _harmonic(t, y, args):
    # Linear, so the implicit presets' Newton (Chord) iterations solve each stage exactly.
    del t, args
    return jnp.stack([-y[1], y[0]])


def _exact(y0, omega, t):
    c, s = np.cos(omega * t), np.sin(omega * t)
    return np.array([c * y0[0] - s * y0[1], s * y0[0] + c * y0[1]])


@eqx.filter_jit
def _solve(integrator, vector_field, y0, t1):
    return integrator.integrate(vector_field, y0, jnp.zeros(1), t1)


def _final_error(name, vector_field, omega, steps, t1=1.0):
    integrator = ll.make_integrator(name, diffrax.ConstantStepSize(), substeps=steps)
    y0 = jnp.array([0.6, 0.3])
    y1, info = _solve(integrator, vector_field, y0, jnp.asarray(t1))
    assert bool(info["solver_ok"])
    return float(np.max(np.abs(np.asarray(y1) - _exact(np.asarray(y0), omega, t1))))


# Per order, the time span and step counts that keep the error between about 1e-2 and 1e-12.
STEPS = {
    1: (1.0, (256, 512, 1024)), 2: (1.0, (32, 64, 128)), 3: (1.0, (16, 32, 64)), 4: (1.0, (8, 16, 32)),
    5: (1.0, (8, 16, 32)), 8: (20.0, (80, 120, 160)),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", [name for name in SOLVERS if name != "semi_implicit_euler"])
def test_declared_order_is_the_convergence_order(name):
    preset = SOLVERS[name]
    with jax.enable_x64(True):
        if preset.implicit:
            vector_field, omega = _harmonic, 1.0
        else:
            vector_field, omega = _rotation, 1.0 + 0.6**2 + 0.3**2
        t1, steps = STEPS[preset.order]
        errors = [_final_error(name, vector_field, omega, k, t1=t1) for k in steps]
    assert all(1e-12 < e < 1e-2 for e in errors), errors
    slope = np.polyfit(np.log(t1 / np.array(steps)), np.log(errors), 1)[0]
    if name == "dopri8":
        # On this problem Dopri8's local slopes climb from 9.1 to 9.7 before round-off
        # (its eighth-order error term is small here): it is at least of its order.
        assert slope > preset.order - 0.3, (name, slope, errors)
    else:
        assert abs(slope - preset.order) < 0.3, (name, slope, errors)


def test_declared_stages_and_evaluations_match_the_tableaux():
    for name, preset in SOLVERS.items():
        solver = preset.make_solver()
        assert preset.implicit == isinstance(solver, diffrax.AbstractImplicitSolver), name
        tableau = getattr(solver, "tableau", None)
        if isinstance(tableau, diffrax.ButcherTableau):
            assert preset.stages == len(tableau.c) + 1, name
            if not preset.implicit:
                assert preset.evaluations_per_step == preset.stages - int(tableau.fsal), name
            assert preset.error_estimate == bool(np.any(np.asarray(tableau.b_error) != 0)), name


def test_register_a_solver_and_use_it_by_name():
    names_before = tuple(ll.SOLVER_PRESETS)
    preset = ll.register_solver("bosh3", diffrax.Bosh3, order=3, description="Bogacki-Shampine 3(2)")
    try:
        assert ll.SOLVER_PRESETS[-1] == "bosh3" and len(ll.SOLVER_PRESETS) == len(names_before) + 1
        assert (preset.stages, preset.evaluations_per_step, preset.error_estimate) == (4, 3, True)
        integrator = ll.make_integrator("bosh3")
        assert isinstance(integrator.solver, diffrax.Bosh3) and integrator.adaptive
        env = ll.CartPole(solver="bosh3", stepsize_controller=diffrax.ConstantStepSize())
        assert isinstance(env.integrator.solver, diffrax.Bosh3)
        assert solver_from_spec("BOSH3") == "bosh3"
        assert describe_solver(diffrax.Bosh3()).name == "bosh3"
        with pytest.raises(ValueError, match="exists already"):
            ll.register_solver("bosh3", diffrax.Bosh3, order=3)
    finally:
        ll.unregister_solver("bosh3")
    assert tuple(ll.SOLVER_PRESETS) == names_before
    assert describe_solver(diffrax.Bosh3()).name == "Bosh3"
    with pytest.raises(ValueError, match="built-in"):
        ll.unregister_solver("rk4")


@pytest.mark.parametrize(
    "arguments, match",
    [
        (dict(name="a:b", solver=diffrax.Bosh3, order=3), "name"),
        (dict(name="x", solver=diffrax.Bosh3, order=0), "order"),
        (dict(name="x", solver=lambda: 3, order=3), "diffrax solver"),
        (dict(name="x", solver=diffrax.Bosh3, order=3, stages=0), "stages"),
    ],
)
def test_register_solver_refuses_bad_input(arguments, match):
    with pytest.raises((ValueError, TypeError), match=match):
        ll.register_solver(arguments.pop("name"), arguments.pop("solver"), **arguments)
    assert "x" not in ll.SOLVERS


def test_solver_specs():
    assert solver_from_spec("RK4") == "rk4"
    assert isinstance(solver_from_spec("diffrax:Bosh3"), diffrax.Bosh3)  # a class, built
    assert isinstance(solver_from_spec("lerax_like:RK4"), ll.RK4)
    for spec, match in [("nope", "unknown solver"), ("diffrax:Nope", "no attribute"), ("math:pi", "no diffrax")]:
        with pytest.raises(ValueError, match=match):
            solver_from_spec(spec)
