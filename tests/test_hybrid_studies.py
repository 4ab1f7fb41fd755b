"""The studies through located frictional contact: `RollingDisk` and the walled cart-pole with cart friction.

Their reference is SciPy's solve of the same hybrid system (`lerax_like.analysis.modes_reference`),
itself checked against references typed from the equations in `test_rolling_disk.py` and
`test_contact_friction.py`. Here:

- `lerax-like study`: errors against it fall at the solver's order through the located events
  (the disk's motion is piecewise polynomial: Euler's first order, RK4 exact to round-off);
- `lerax-like gradients`: its gradient (central differences of the SciPy reference) meets the
  disk's closed form `dx(T)/dmu = -v0^2 / (18 mu^2 g)` and the located model's own AD;
- `lerax-like gradient-variance` runs on both scenes.
"""

import csv
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis.gradient_accuracy import GradientStudyConfig, run_gradient_study
from lerax_like.analysis.gradient_variance import GradientVarianceConfig, run_gradient_variance
from lerax_like.analysis.sweeps import SolverSweep, tolerance_pairs
from lerax_like.cli import main


# Walls 0.1 m from the centre, so that the quick study's random pushes reach them.
WALLED = {"restitution": 0.8, "track_limit": 0.1, "x_threshold": math.inf, "cart_static_friction": 0.3,
          "cart_kinetic_friction": 0.15}


def _rows(path):
    with open(path, newline="") as file:
        return {(row["schedule"], row["solver"], int(row["substeps"])): row for row in csv.DictReader(file)}


def _events(env, record, schedule):
    """Impacts and switches located by the env's own step along the study's trajectories."""
    inputs = jnp.asarray(record["schedules"][schedule]["inputs"])

    def trajectory(y0):
        def body(state, u):
            state, info = env.evolve(state, u)
            return state, (info.get("impacts", 0), info["switches"])

        return jax.lax.scan(body, ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int)), inputs)[1]

    impacts, switches = jax.jit(jax.vmap(trajectory))(jnp.asarray(record["initial_states"]))
    return int(np.sum(impacts)), int(np.sum(switches))


def _study(scene, keywords, solvers, substeps, horizon, out):
    arguments = ["study", scene, "--quick", "--no-plot", "--no-progress", "--horizon", str(horizon), "--out", str(out),
                 "--substeps", *substeps]
    arguments += [item for solver in solvers for item in ("--solver", solver)]
    arguments += [item for key, value in keywords.items() for item in ("--scene-keyword", f"{key}={value}")]
    assert main(arguments) == 0
    with open(out / f"{scene}.json") as file:
        record = json.load(file)
    assert record["reference"]["method"] == "DOP853"
    return _rows(out / f"{scene}.csv"), record


@pytest.mark.slow
def test_study_of_the_rolling_disk_converges_at_the_solvers_order(tmp_path):
    # At 256 substeps a rolling disk drifted off x_dot = r angle_dot by 1e-13 within a step, once read
    # as a slip at the next step's start: Euler's and RK4's max_error were 0.27 (floor_contact).
    rows, record = _study("RollingDisk", {}, ("euler", "rk4"), ("16", "64", "256"), 12, tmp_path)
    env = ll.make("RollingDisk")
    for schedule in ("recorded", "zero"):
        assert _events(env, record, schedule)[1] >= 1, "the disks must skid, then roll"
        errors = [float(rows[schedule, "euler", n]["max_error"]) for n in (16, 64, 256)]
        # First order: a quarter of the step, a quarter of the error.
        assert all(2.5 < coarse / fine < 6 for coarse, fine in zip(errors, errors[1:])), errors
        # Constant accelerations between located switches: RK4 is exact to round-off.
        assert all(float(rows[schedule, "rk4", n]["max_error"]) < 1e-12 for n in (16, 64, 256))
    for row in rows.values():
        assert row["solver_ok"] == "True" and float(row["reference_floor"]) < 1e-11
        assert row["energy_drift"] in ("", "nan")  # the floor's friction takes energy by physics


@pytest.mark.slow
def test_study_of_the_walled_cart_pole_with_friction_converges_at_the_solvers_order(tmp_path):
    rows, record = _study("CartPoleContinuous", WALLED, ("rk4",), ("1", "2"), 20, tmp_path)
    impacts, switches = _events(ll.make("CartPoleContinuous", **WALLED), record, "recorded")
    assert impacts >= 1 and switches >= 1, "the study must go through impacts and switches to test anything"
    for row in rows.values():
        assert row["solver_ok"] == "True" and float(row["reference_floor"]) < 1e-11
    # Fourth order through impacts and switches: halving the step divides the error by about 16.
    coarse, fine = (float(rows["recorded", "rk4", n]["error"]) for n in (1, 2))
    assert fine < 1e-6 and 8 < coarse / fine < 32


def final_position(ys):
    """The position after the last env step."""
    return ys[-1, 0]


@pytest.mark.slow
def test_gradient_reference_of_the_launched_disk_meets_the_closed_form():
    mu, v0, g, steps = 0.4, 2.0, 9.81, 6  # t* = v0 / (3 mu g) = 0.17 s, T = 0.3 s
    config = GradientStudyConfig(
        scene="RollingDisk", scene_kwargs={"static_friction": 1.0, "kinetic_friction": mu, "gravity": g},
        sweeps=(SolverSweep("tsit5", tolerances=tolerance_pairs([8])),), horizon=steps,
        initial_state=(0.0, 0.1, 0.0, v0, 0.0, 0.0), actions=np.zeros((steps, 1)), parameters=("kinetic_friction",),
        cost=final_position, repeats=1,
    )
    result = run_gradient_study(config)
    reference = result.record["reference"]
    closed_form = -(v0**2) / (18 * mu**2 * g)
    (gradient,) = reference["gradient"]
    assert "modes_reference" in reference["solver"]
    assert abs(gradient - closed_form) < 1e-8 * abs(closed_form)
    assert reference["floor"] < 1e-7 and reference["dopri8_discrepancy"] < 1e-8
    (row,) = result.rows
    assert row["solver_ok"] and row["error"] < 1e-8


@pytest.mark.slow
def test_gradient_reference_of_the_walled_cart_pole_with_friction_meets_the_located_ad():
    # Sliding into the wall 0.05 m away: the impact at about 0.1 s, the rebound stops by 0.2 s.
    keywords = {**WALLED, "cart_static_friction": 0.4, "cart_kinetic_friction": 0.3}
    config = GradientStudyConfig(
        scene="CartPoleContinuous", scene_kwargs=keywords, sweeps=(SolverSweep("rk4", substeps=(2,)),), horizon=10,
        initial_state=(0.05, 0.6, 0.05, 0.0), actions=np.zeros((10, 1)),
        parameters=("pole_mass", "cart_kinetic_friction"), repeats=1,
    )
    result = run_gradient_study(config)
    reference = result.record["reference"]
    assert result.record["parameter_names"] == ["pole_mass", "cart_kinetic_friction"]
    # Central differences of SciPy's solve and the located model's AD (Dopri8, forward mode) agree
    # within the differences' own floor (the stencil at h against 2h: about 16 times the error at h;
    # the stop, 5 ms before a sampled instant, gives the loss large fifth derivatives).
    assert reference["floor"] < 1e-5 and reference["dopri8_discrepancy"] < reference["floor"]
    (row,) = result.rows
    assert row["solver_ok"] and row["error"] < 1e-5
    env = ll.make("CartPoleContinuous", **keywords)
    record = {"schedules": {"zero": {"inputs": np.zeros((10, 1))}}, "initial_states": [config.initial_state]}
    impacts, switches = _events(env, record, "zero")
    assert impacts == 1 and switches >= 1


@pytest.mark.slow
@pytest.mark.parametrize("scene, keywords", [("RollingDisk", {}), ("CartPoleContinuous", WALLED)])
def test_gradient_variance_runs_through_located_frictional_contact(scene, keywords):
    # The float32 digit loss too: a float32 env's event condition under jax_enable_x64 once failed
    # to trace in diffrax's event `cond` (float32 against its float64 `0.0`), walls as well.
    config = GradientVarianceConfig.default(
        scene, scene_kwargs=keywords, horizons=(5,), samples=4, reference_samples=8, lyapunov=False,
        precision_horizon=5, policies=("open_loop",),
    )
    result = run_gradient_variance(config)
    assert {row["estimator"] for row in result.rows} == {"first_order", "zeroth_order", "alpha_order"}
    assert all(math.isfinite(row["gradient_norm"]) and row["failed_samples"] == 0 for row in result.rows)
    (precision,) = result.record["precision"]
    assert all(error < 1e-4 for error in precision["relative_error"])
