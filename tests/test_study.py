"""The study's pieces: reference, cost count, the `lerax-like study --quick` output."""

import csv
import json
import math

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis import CSV_COLUMNS, evaluations_per_step, reference_trajectories
from lerax_like.analysis.rollout_check import preset_rollouts
from lerax_like.cli import main


def test_reference_agrees_with_an_independent_method(getkey):
    # DOP853 (explicit, order 8) and Radau IIA (implicit, order 5) share nothing but the
    # vector field; both at rtol = atol = 1e-13.
    env = ll.CartPole()
    y0s = jnp.stack([env.initial(key=getkey()).y for _ in range(2)])
    actions = jax.random.bernoulli(getkey(), 0.5, (25,)).astype(int)
    inputs = np.asarray(jax.vmap(env.physical_input)(actions))
    explicit = reference_trajectories(env.dynamics, y0s, inputs, 0.02, method="DOP853")
    implicit = reference_trajectories(env.dynamics, y0s, inputs, 0.02, method="Radau")
    assert explicit.shape == (2, 25, 4)
    assert np.max(np.abs(explicit)) > 0.1  # the pole has moved
    assert np.max(np.abs(explicit - implicit)) < 1e-10


@pytest.mark.parametrize(
    "solver, controller",
    [
        (diffrax.Heun(), diffrax.ConstantStepSize()),
        (ll.RK4(), diffrax.ConstantStepSize()),
        # A loose start (dt0 = 0.05) so that the controller rejects a step.
        (diffrax.Tsit5(), diffrax.PIDController(rtol=1e-8, atol=1e-10)),
    ],
)
def test_vector_field_evaluations_from_the_tableau_match_a_count(solver, controller):
    # Count the evaluations diffrax actually makes, with a host callback.
    calls = []
    dynamics = ll.CartPoleDynamics()

    def counted(t, y, u):
        jax.debug.callback(lambda: calls.append(1))
        return dynamics.vector_field(t, y, u)

    y0 = jnp.array([0.0, 0.1, 0.3, -0.2])
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(counted), solver, t0=0.0, t1=0.1, dt0=0.05, y0=y0, args=jnp.array([3.0]),
        stepsize_controller=controller, max_steps=1000,
    )
    jax.block_until_ready(solution.ys)
    if isinstance(controller, diffrax.PIDController):
        assert int(solution.stats["num_rejected_steps"]) >= 1
    per_accepted, per_rejected, per_solve = evaluations_per_step(solver)
    accepted = int(solution.stats["num_accepted_steps"])
    rejected = int(solution.stats["num_rejected_steps"])
    assert accepted >= 2
    assert len(calls) == accepted * per_accepted + rejected * per_rejected + per_solve


@pytest.fixture(scope="module")
def quick_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    assert main(["study", "CartPole", "--quick", "--out", str(out), "--no-progress"]) == 0
    return out


def _read(out):
    with open(out / "CartPole.csv", newline="") as file:
        return list(csv.DictReader(file))


@pytest.mark.slow
def test_quick_study_writes_csv_png_json(quick_study):
    rows = _read(quick_study)
    required = {"scene", "solver", "controller", "dt", "rtol", "atol", "error", "seconds", "steps",
                "max_error", "vector_field_evaluations", "dtype", "reference_method", "reference_tolerance"}
    assert required <= set(rows[0]) and set(rows[0]) == set(CSV_COLUMNS)
    assert {row["scene"] for row in rows} == {"CartPole"}
    assert {row["dtype"] for row in rows} == {"float64"}
    assert {row["reference_method"] for row in rows} == {"DOP853"}
    assert all(float(row["reference_tolerance"]) <= 1e-12 for row in rows)
    assert all(float(row["seconds"]) > 0 and float(row["steps"]) > 0 for row in rows)
    assert all(float(row["max_error"]) >= float(row["error"]) for row in rows)
    adaptive = [row for row in rows if row["controller"] == "PIDController"]
    assert adaptive and all(row["rtol"] and row["atol"] and not row["dt"] for row in adaptive)
    # Tighter tolerances cost at least as many evaluations.
    evaluations = [float(r["vector_field_evaluations"]) for r in adaptive if r["schedule"] == "recorded"]
    assert evaluations == sorted(evaluations)
    png = (quick_study / "CartPole.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    record = json.loads((quick_study / "CartPole.json").read_text())
    assert record["config"]["seed"] == 0 and record["config"]["horizon"] == 50
    assert np.asarray(record["initial_states"]).shape == (4, 4)
    assert record["environment"]["versions"]["jax"] == jax.__version__
    assert record["reference"]["method"] == "DOP853"


@pytest.mark.slow
@pytest.mark.parametrize("solver, order", [("euler", 1), ("rk4", 4)])
def test_quick_study_gives_the_orders(quick_study, solver, order):
    for schedule in ("recorded", "zero"):
        rows = [r for r in _read(quick_study) if r["solver"] == solver and r["schedule"] == schedule]
        dt = np.array([float(r["dt"]) for r in rows])
        error = np.array([float(r["error"]) for r in rows])
        keep = (error > 1e-11) & (error < 1e-2)
        assert np.count_nonzero(keep) >= 2, error
        slope = np.polyfit(np.log(dt[keep]), np.log(error[keep]), 1)[0]
        assert abs(slope - order) < 0.5, (schedule, slope)


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_rollout_of_presets_against_scipy():
    rows = preset_rollouts("CartPole", steps=20, presets=("euler", "rk4"), repeats=1)
    errors = {row["solver"]: row["final_error"] for row in rows}
    assert all(row["solver_ok"] and row["seconds"] > 0 for row in rows)
    # Gymnasium's Euler step at dt = 0.02 is far from the true motion; RK4 is close.
    assert errors["rk4"] < 1e-5 < errors["euler"] < 1.0
    assert not math.isnan(errors["rk4"])
