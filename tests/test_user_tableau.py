"""A user's own Butcher tableau: run by the installed `lerax-like` command from the user's
folder, at its order, with dense output of its order."""

import csv
import os
import re
import shutil
import subprocess
import textwrap

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis.convergence import fit_order


# Ralston's third-order method (Ralston 1962; Hairer, Norsett & Wanner, Table II.1.1 family),
# typed from the order conditions, nothing taken from diffrax: its last stage sits at
# c = 3/4, so diffrax's default dense output (a cubic Hermite whose end slope is the last
# stage) is only second order.
USER_MODULE = textwrap.dedent(
    """
    from typing import ClassVar

    import diffrax
    import numpy as np


    class Ralston3(diffrax.AbstractERK):
        tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
            c=np.array([1 / 2, 3 / 4]),
            b_sol=np.array([2 / 9, 1 / 3, 4 / 9]),
            b_error=np.zeros(3),
            a_lower=(np.array([1 / 2]), np.array([0.0, 3 / 4])),
        )
        interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation.from_k

        def order(self, terms):
            return 3


    RALSTON3 = Ralston3()
    """
)


def _user_solver(tmp_path):
    namespace = {}
    exec(compile(USER_MODULE, str(tmp_path / "mymethods.py"), "exec"), namespace)
    return namespace["RALSTON3"]


def _rotation(t, y, args):
    # y' = (1 + |y|^2) J y: the radius is conserved, so y(t) = R((1 + r0^2) t) y0 exactly.
    del t, args
    return (1.0 + y[0] ** 2 + y[1] ** 2) * jnp.stack([-y[1], y[0]])


def _exact(y0, ts):
    omega = 1.0 + float(np.sum(y0**2))
    c, s = np.cos(omega * ts), np.sin(omega * ts)
    return np.stack([c * y0[0] - s * y0[1], s * y0[0] + c * y0[1]], axis=-1)


# Inside the steps, never on a step's end for 8 to 64 steps over [0, 1].
TIMES = np.linspace(0.0, 1.0, 41)[1:-1] + 0.003


def _dense_errors(solver, steps, *, hermite_both_ends: bool):
    y0 = np.array([0.6, 0.3])
    with jax.enable_x64(True):
        errors = []
        for n in steps:
            if hermite_both_ends:
                integrator = ll.make_integrator(solver, diffrax.ConstantStepSize(), substeps=n)
                ys, ok = integrator.dense_states(_rotation, jnp.asarray(y0), jnp.zeros(1), 1.0, jnp.asarray(TIMES))
                assert bool(ok)
            else:  # diffrax's own dense output of the same steps
                ys = diffrax.diffeqsolve(
                    diffrax.ODETerm(_rotation), solver, 0.0, 1.0, 1.0 / n, jnp.asarray(y0),
                    saveat=diffrax.SaveAt(ts=jnp.asarray(TIMES)), max_steps=n,
                ).ys
            errors.append(float(np.max(np.abs(np.asarray(ys) - _exact(y0, TIMES)))))
    return np.array(errors)


STEPS = (8, 16, 32, 64)


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_a_users_tableau_gets_dense_output_of_its_order(tmp_path):
    solver = _user_solver(tmp_path)
    assert ll.solver_facts(solver).order == 3
    ours = _dense_errors(solver, STEPS, hermite_both_ends=True)
    diffrax_own = _dense_errors(solver, STEPS, hermite_both_ends=False)
    slope, points = fit_order(1.0 / np.array(STEPS), ours, ceiling=1.0)
    own_slope, _ = fit_order(1.0 / np.array(STEPS), diffrax_own, ceiling=1.0)
    assert points == len(STEPS) and abs(slope - 3) < 0.3, (slope, ours)
    # The trap this avoids: the last stage as the end slope gives a second-order interpolant.
    assert abs(own_slope - 2) < 0.3, (own_slope, diffrax_own)


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
@pytest.mark.parametrize("name", ["rk4", "heun", "tsit5", "dopri8"])
def test_dense_output_keeps_the_presets_orders(name):
    # Hermite from both ends is of order min(p, 4); the methods with an interpolant of their
    # own keep it (Tsit5's and Dopri8's are of higher order than four).
    solver = ll.SOLVERS[name].make_solver()
    steps = (4, 8, 16) if name in ("tsit5", "dopri8") else STEPS
    errors = _dense_errors(solver, steps, hermite_both_ends=True)
    slope, _ = fit_order(1.0 / np.array(steps), errors, floor=1e-13, ceiling=1.0)
    expected = min(ll.SOLVERS[name].order, 4)
    assert slope > expected - 0.3, (name, slope, errors)


def _console_script():
    script = shutil.which("lerax-like")
    if script is None:
        pytest.skip("the lerax-like console script is not installed (pip install -e .)")
    return script


@pytest.mark.slow
def test_the_installed_command_studies_a_tableau_from_the_working_directory(tmp_path):
    (tmp_path / "mymethods.py").write_text(USER_MODULE)
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    completed = subprocess.run(
        [_console_script(), "study", "CartPole", "--quick", "--no-plot", "--no-progress", "--out", "out",
         "--solver", "mymethods:RALSTON3"],
        cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=900,
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    orders = {
        match.group(1): float(match.group(2))
        for match in re.finditer(r"^\s*(\w+) Ralston3\s+order ([0-9.]+)", completed.stdout, re.MULTILINE)
    }
    assert orders and all(abs(order - 3) < 0.5 for order in orders.values()), completed.stdout
    # The dense error over the study's grid converges at the same order.
    with open(tmp_path / "out" / "CartPole.csv", newline="") as file:
        rows = [r for r in csv.DictReader(file) if r["solver"] == "Ralston3" and r["schedule"] == "zero"]
    slope, points = fit_order([float(r["dt"]) for r in rows], [float(r["linf_error"]) for r in rows], floor=1e-11)
    assert points >= 2 and abs(slope - 3) < 0.5, (slope, rows)
