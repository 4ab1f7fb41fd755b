"""Any solver in the study: a user's own tableau by `module:attribute`, the preset registry
with its orders, dense errors against SciPy's dense output, and a study without matplotlib."""

import csv
import json
import math
import os
import subprocess
import sys
import textwrap

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis import SolverSweep, StudyConfig, dense_reference_trajectories, run_study
from lerax_like.analysis.convergence import convergence_orders
from lerax_like.analysis.study import write_study
from lerax_like.analysis.tables import format_orders, format_table
from lerax_like.cli import main


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Kutta's third-order method (Kutta 1901; Hairer, Norsett & Wanner, Table II.1.1), written
# out by hand as a diffrax Runge-Kutta method: nothing taken from diffrax's own tableaux.
USER_MODULE = textwrap.dedent(
    """
    from typing import ClassVar

    import diffrax
    import numpy as np


    class Kutta3(diffrax.AbstractERK):
        tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
            c=np.array([1 / 2, 1.0]),
            b_sol=np.array([1 / 6, 2 / 3, 1 / 6]),
            b_error=np.zeros(3),
            a_lower=(np.array([1 / 2]), np.array([-1.0, 2.0])),
        )
        interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation.from_k


    KUTTA3 = Kutta3()
    """
)


def _run_cli(arguments, *, pythonpath=(), prelude="", timeout=900):
    """`python -m lerax_like ARGUMENTS` from the repository root, as a user runs it."""
    environment = dict(os.environ)
    environment["PYTHONPATH"] = os.pathsep.join([ROOT, *pythonpath, environment.get("PYTHONPATH", "")])
    code = prelude + "import sys\nfrom lerax_like.cli import main\nsys.exit(main(sys.argv[1:]))\n"
    return subprocess.run(
        [sys.executable, "-c", code, *arguments], cwd=ROOT, env=environment, capture_output=True, text=True,
        timeout=timeout,
    )


def _fitted_slope(rows, low=1e-11, high=1e-2):
    dt = np.array([float(r["dt"]) for r in rows])
    error = np.array([float(r["error"]) for r in rows])
    keep = (error > low) & (error < high)
    assert np.count_nonzero(keep) >= 2, error
    return np.polyfit(np.log(dt[keep]), np.log(error[keep]), 1)[0]


@pytest.fixture(scope="module")
def user_solver_study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("user_solver")
    (folder / "hand_made_methods.py").write_text(USER_MODULE)
    out = folder / "out"
    completed = _run_cli(
        ["study", "CartPole", "--quick", "--no-progress", "--out", str(out), "--solver", "rk4",
         "--solver", "hand_made_methods:KUTTA3", "--solver", "diffrax:Bosh3"],
        pythonpath=[str(folder)],
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    with open(out / "CartPole.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    record = json.loads((out / "CartPole.json").read_text())
    return completed.stdout, rows, record, out


@pytest.mark.slow
@pytest.mark.parametrize("name, order", [("rk4", 4), ("Kutta3", 3), ("Bosh3", 3)])
def test_user_solvers_reach_their_orders(user_solver_study, name, order):
    _, rows, _, _ = user_solver_study
    for schedule in ("recorded", "zero"):
        line = [r for r in rows if r["solver"] == name and r["schedule"] == schedule and r["controller"] == "ConstantStepSize"]
        assert len(line) >= 3
        slope = _fitted_slope(line)
        assert abs(slope - order) < 0.5, (name, schedule, slope)


@pytest.mark.slow
def test_user_solvers_are_named_in_every_output(user_solver_study):
    stdout, rows, record, out = user_solver_study
    names = {"rk4", "Kutta3", "Bosh3"}
    assert {r["solver"] for r in rows} == names
    # Bosh3 has an error estimate: swept over tolerances too; the others are not.
    assert {r["label"] for r in rows} == names | {"Bosh3 (PID)"}
    assert {sweep["name"] for sweep in record["config"]["sweeps"]} == names
    assert set(record["figure"]["legend"]) == names | {"Bosh3 (PID)"}
    assert (out / "CartPole.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    table_solvers = {line.split()[1] for line in stdout.splitlines() if line.startswith(("recorded ", "zero "))}
    assert names <= table_solvers
    assert "nan" not in stdout.split("Convergence orders")[1]


@pytest.mark.slow
def test_dense_errors_bound_the_step_errors(user_solver_study):
    _, rows, _, _ = user_solver_study
    for row in rows:
        error, max_error = float(row["error"]), float(row["max_error"])
        l2_error, linf_error = float(row["l2_error"]), float(row["linf_error"])
        # The dense grid holds every env-step end, so its maximum bounds the ends'.
        assert linf_error >= max_error >= error > 0, row
        assert 0 < l2_error <= linf_error, row


@pytest.mark.slow
def test_dense_reference_agrees_with_radau(getkey):
    # The study's dense reference (DOP853's continuous extension) against Radau IIA's,
    # and against Radau restarted at every grid point (no interpolation at all).
    from scipy.integrate import solve_ivp

    env = ll.CartPole()
    y0s = np.stack([np.asarray(env.initial(key=getkey()).y) for _ in range(2)])
    y0s[1, 2] = 0.2  # a larger swing
    actions = jax.random.bernoulli(getkey(), 0.5, (20,)).astype(int)
    inputs = np.asarray(jax.vmap(env.physical_input)(actions))
    fractions = np.arange(1, 8) / 8
    ends, inside = dense_reference_trajectories(env.dynamics, y0s, inputs, 0.02, fractions)
    radau_ends, radau_inside = dense_reference_trajectories(env.dynamics, y0s, inputs, 0.02, fractions, method="Radau")
    assert inside.shape == (2, 20, 7, 4) and ends.shape == (2, 20, 4)
    assert np.max(np.abs(inside)) > 0.1
    assert np.max(np.abs(ends - radau_ends)) < 1e-10
    assert np.max(np.abs(inside - radau_inside)) < 1e-10

    dynamics = env.dynamics
    f = jax.jit(lambda y, u: dynamics.vector_field(0.0, y, u))
    for b in range(2):
        y = y0s[b]
        for k, u in enumerate(inputs):
            times = np.concatenate([[0.0], fractions * 0.02, [0.02]])
            for j in range(len(times) - 1):
                y = solve_ivp(lambda t, y: np.asarray(f(y, u)), (times[j], times[j + 1]), y, method="Radau",
                              rtol=1e-13, atol=1e-13).y[:, -1]
                expected = inside[b, k, j] if j < len(fractions) else ends[b, k]
                assert np.max(np.abs(y - expected)) < 1e-10, (b, k, j)


@pytest.mark.slow
def test_a_diffrax_solver_object_runs_through_every_output(tmp_path):
    # `SolverSweep(diffrax.Bosh3())` used to crash the table, the orders and the JSON.
    sweeps = (SolverSweep(diffrax.Bosh3(), substeps=(2,)), SolverSweep(diffrax.Bosh3, tolerances=((1e-6, 1e-9),)))
    config = StudyConfig(scene="CartPole", sweeps=sweeps, schedules=("zero",), horizon=5, batch=1, repeats=1)
    result = run_study(config, progress=False)
    assert {row["solver"] for row in result.rows} == {"Bosh3"}
    assert {row["label"] for row in result.rows} == {"Bosh3", "Bosh3 (PID)"}
    assert "Bosh3 (PID)" in format_table(result.rows)
    paths = write_study(result, tmp_path, plot=False)
    record = json.loads(open(paths["json"]).read())
    assert [sweep["name"] for sweep in record["config"]["sweeps"]] == ["Bosh3", "Bosh3"]
    for row in result.rows:
        assert row["linf_error"] >= row["max_error"] >= row["error"]
    # Errors on the dense grid: at least the step ends', and the midpoints of a Hermite
    # interpolant within its own order: at most a few times the ends'.
    assert all(row["linf_error"] < 10 * row["max_error"] for row in result.rows)


def _rows(errors, step_sizes, solver="euler", floor=1e-14):
    return [
        {"scene": "Pendulum", "schedule": "recorded", "solver": solver, "controller": "ConstantStepSize",
         "dt": h, "error": e, "max_error": e, "reference_floor": floor, "order": 1}
        for h, e in zip(step_sizes, errors)
    ]


def test_orders_out_of_the_asymptotic_range_are_said_in_words():
    # Pendulum's Euler in the quick study: errors of about 2 pi that first grow, then shrink.
    rows = _rows([3.1, 6.2, 4.0], [0.05 / 16, 0.05 / 64, 0.05 / 256][::-1])
    (entry,) = convergence_orders(rows)
    assert entry["order"] is None and "asymptotic range" in entry["note"]
    assert "does not fall steadily" in entry["note"]
    text = format_orders([entry])
    assert "nan" not in text and "not in the asymptotic range" in text
    json.dumps(entry, allow_nan=False)  # no NaN in the JSON either
    # At the floor: said so.
    (entry,) = convergence_orders(_rows([1e-15, 2e-15], [0.01, 0.02]))
    assert entry["order"] is None and "floor" in entry["note"]


@pytest.mark.slow
def test_study_without_matplotlib(tmp_path):
    prelude = "import sys\nsys.modules['matplotlib'] = None  # import matplotlib now raises ImportError\n"
    completed = _run_cli(
        ["study", "CartPole", "--quick", "--no-progress", "--solver", "rk4", "--out", str(tmp_path)], prelude=prelude
    )
    assert completed.returncode == 0, completed.stderr[-3000:]
    assert "schedule  solver" in completed.stdout and "rk4" in completed.stdout
    skipped = [line for line in completed.stdout.splitlines() if line.startswith("plot skipped")]
    assert len(skipped) == 1 and "pip install" in skipped[0]
    assert (tmp_path / "CartPole.csv").exists() and (tmp_path / "CartPole.json").exists()
    assert not (tmp_path / "CartPole.png").exists()
    assert "Traceback" not in completed.stderr


def test_solver_listing_shows_orders():
    completed = _run_cli(["solvers"])
    assert completed.returncode == 0, completed.stderr
    lines = {line.split()[0]: line.split() for line in completed.stdout.splitlines()[1:] if line.strip()}
    assert lines["rk4"][1] == "4" and lines["dopri8"][1] == "8" and lines["kvaerno5"][4] == "implicit"


@pytest.mark.parametrize("command", ["study", "gradients"])
def test_bad_solver_names_are_usage_errors(command, capsys):
    for spec, words in [("rk5", "unknown solver"), ("no_such_module:X", "cannot import"),
                        ("diffrax:NoSuchSolver", "has no attribute"), ("math:pi", "no diffrax solver")]:
        with pytest.raises(SystemExit) as exit_info:
            main([command, "CartPole", "--quick", "--solver", spec])
        assert exit_info.value.code == 2
        assert words in capsys.readouterr().err, spec


@pytest.mark.slow  # 3.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_solvers_are_swept_by_what_they_offer():
    from lerax_like.analysis import sweeps_for

    sweeps = sweeps_for(["rk4", diffrax.Bosh3(), "kvaerno5", diffrax.Bosh3()], quick=True)
    kinds = [(sweep.name, sweep.adaptive) for sweep in sweeps]
    # No error estimate: substeps only; an estimate: substeps and tolerances; two solvers
    # of one class are told apart.
    assert kinds == [("rk4", False), ("Bosh3", False), ("Bosh3", True), ("kvaerno5", False), ("kvaerno5", True),
                     ("Bosh3#2", False), ("Bosh3#2", True)]
    stiff = sweeps_for(["rk4", "kvaerno5"], stiff=True)
    assert [(sweep.name, sweep.adaptive) for sweep in stiff] == [("rk4", False), ("kvaerno5", True)]
    with pytest.raises(ValueError, match="no error estimate"):
        SolverSweep("rk4", tolerances=((1e-6, 1e-9),))
