"""The registry of solver presets: declared orders and stages checked against the methods."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.integrate import solver_from_spec
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


@pytest.mark.parametrize("name", [name for name in SOLVERS if not SOLVERS[name].implicit])
def test_evaluations_per_step_match_a_count(name):
    # Count the evaluations the solver actually makes over three constant steps, with a
    # host callback: `solver_facts` reads them from the tableau (or knows them, for the
    # Euler methods), the count does not.
    calls = []
    dynamics = ll.CartPoleDynamics()

    def counted(t, y, u):
        jax.debug.callback(lambda: calls.append(1))
        return dynamics.vector_field(t, y, u)

    integrator = ll.make_integrator(name, diffrax.ConstantStepSize(), substeps=3)
    with jax.enable_x64(True):
        y1, info = integrator.integrate(
            counted, jnp.array([0.0, 0.1, 0.3, -0.2]), jnp.array([3.0]), 0.06,
            velocity_indices=dynamics.velocity_indices,
        )
        jax.block_until_ready(y1)
    assert bool(info["solver_ok"])
    facts = ll.solver_facts(integrator.solver)
    assert facts == ll.solver_facts(SOLVERS[name].make_solver())
    assert (SOLVERS[name].stages, SOLVERS[name].evaluations_per_step) == (facts.stages, facts.evaluations_per_step)
    assert len(calls) == 3 * facts.evaluations_per_step + facts.evaluations_per_solve, (name, len(calls))
    if name != "semi_implicit_euler":  # the partitioned method evaluates twice in one stage each
        assert facts.evaluations_per_rejected_step == facts.stages


@pytest.mark.slow  # 5.4 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_error_estimates_and_kinds_match_the_solvers():
    # What an adaptive controller needs: an error output from a step, whatever the solver.
    for name, preset in SOLVERS.items():
        solver = preset.make_fixed_step_solver() if preset.implicit else preset.make_solver()
        assert preset.implicit == isinstance(solver, diffrax.AbstractImplicitSolver), name
        term = diffrax.ODETerm(lambda t, y, args: -y)
        y0 = jnp.ones(2)
        if name == "semi_implicit_euler":
            term = ll.integrate.ProjectedODETerm(lambda t, y, args: jnp.stack([y[1], -y[0]]), velocity_indices=(1,))
        t0, t1 = jnp.asarray(0.0), jnp.asarray(0.1)
        error = solver.step(term, t0, t1, y0, None, solver.init(term, t0, t1, y0, None), made_jump=False)[1]
        has_error = error is not None and bool(jnp.any(error != 0))
        assert preset.error_estimate == has_error, name


def test_solver_facts_refuse_a_solver_of_several_terms():
    with pytest.raises(ValueError, match="one ODE term"):
        ll.solver_facts(diffrax.KenCarp3())


def test_register_a_solver_and_use_it_by_name():
    names_before = tuple(ll.SOLVERS.names)
    preset = ll.register_solver("bosh3", diffrax.Bosh3, order=3, description="Bogacki-Shampine 3(2)")
    try:
        assert ll.SOLVERS.names[-1] == "bosh3" and len(ll.SOLVERS.names) == len(names_before) + 1
        assert (preset.stages, preset.evaluations_per_step, preset.error_estimate) == (4, 3, True)
        integrator = ll.make_integrator("bosh3")
        assert isinstance(integrator.solver, diffrax.Bosh3) and integrator.adaptive
        env = ll.make("CartPole", solver="bosh3", stepsize_controller=diffrax.ConstantStepSize())
        assert isinstance(env.integrator.solver, diffrax.Bosh3)
        assert solver_from_spec("BOSH3") == "bosh3"
        assert describe_solver(diffrax.Bosh3()).name == "bosh3"
        with pytest.raises(ValueError, match="exists already"):
            ll.register_solver("bosh3", diffrax.Bosh3, order=3)
    finally:
        ll.unregister_solver("bosh3")
    assert tuple(ll.SOLVERS.names) == names_before
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


def test_the_solver_listing_names_every_column_and_fills_every_count():
    from lerax_like.cli import format_solver_table

    lines = format_solver_table().splitlines()
    header = lines[0].split("  ")
    columns = [cell.strip() for cell in header if cell.strip()]
    assert columns == ["name", "order", "stages", "f-evals/step", "kind", "error estimate", "default controller",
                       "description"]
    rows = {line.split()[0]: line.split() for line in lines[1:]}
    assert set(rows) == set(SOLVERS)
    for name, cells in rows.items():
        assert cells[1] == str(SOLVERS[name].order) and cells[2] == str(SOLVERS[name].stages), cells
    assert rows["semi_implicit_euler"][2:4] == ["2", "2"]
