"""What a work-precision study concludes: one setting for settings that coincide, a cheapest
setting that is the same in every run, energy drift only where energy is conserved, order
guides inside the data."""

import contextlib
import math

import jax
import numpy as np
import pytest

from lerax_like.analysis import SolverSweep, StudyConfig, reference_trajectories, run_study
from lerax_like import make as make_scene
from lerax_like.analysis.figures import order_guide
from lerax_like.analysis.measurements import conserved_quantities
from lerax_like.analysis.recording import read_csv_rows
from lerax_like.analysis.study import VERDICT_TARGETS, read_csv, write_csv
from lerax_like.analysis.tables import format_table
from lerax_like.analysis.verdict import cheapest_at, group_settings, timing_unresolved


def _row(label, rtol, error, steps, seconds, **extra):
    return {
        "schedule": "recorded", "label": label, "solver": label.split()[0], "controller": "PIDController",
        "rtol": rtol, "atol": rtol / 1000, "dt": math.nan, "substeps": "", "error": error, "max_error": error,
        "steps": steps, "rejected_steps": 0.0, "vector_field_evaluations": 13.0 * steps, "seconds": seconds,
        "seconds_spread": 0.05, "timing_floor": 1e-5, "solver_ok": True, **extra,
    }


def test_settings_with_the_same_error_and_steps_are_one_setting():
    # Dopri8 on CartPole: the same 200 steps and the same error at every tolerance, timed
    # differently by noise alone; then a tolerance that does change the steps.
    same = [_row("dopri8 (PID)", 10.0**-e, 8.8e-14, 200.0, seconds) for e, seconds in zip(range(4, 8), (4e-3, 9e-3, 5e-3, 6e-3))]
    tighter = _row("dopri8 (PID)", 1e-8, 7.0e-14, 230.0, 7e-3)
    grouped = group_settings(same + [tighter])
    assert [row["members"] for row in grouped] == [4, 1]
    assert grouped[0]["setting"].startswith("rtol=1e-04..1e-07")
    assert grouped[0]["seconds"] == min(row["seconds"] for row in same)
    # The spread of the members' times is the spread of one setting: noise, and marked so.
    assert timing_unresolved(grouped[0])
    table = format_table(same + [tighter])
    assert table.count("dopri8 (PID)") == 2 and "1e-04..1e-07" in table and "~" in table
    # Cheapest by evaluations: the group, whichever member happened to run fastest.
    best = cheapest_at(same + [tighter], 1e-9)
    assert best["measure"] == "vector_field_evaluations" and best["members"] == 4
    assert best["setting"] == grouped[0]["setting"]


def test_a_time_verdict_counts_only_resolved_timings_and_calls_a_close_race_a_tie():
    # An implicit solver (evaluations unknown) forces the verdict onto time.
    rows = [
        _row("kvaerno5 (PID)", 1e-4, 1e-5, 100.0, 1.0e-3, vector_field_evaluations=math.nan),
        _row("kvaerno3 (PID)", 1e-4, 1e-5, 120.0, 1.1e-3, vector_field_evaluations=math.nan),
        _row("tsit5 (PID)", 1e-4, 1e-5, 9000.0, 2.0e-5),  # below 3x the empty call: unresolved
    ]
    best = cheapest_at(rows, 1e-3)
    assert best["measure"] == "seconds" and best["label"] == "kvaerno5 (PID)"
    assert best["tied_with"] == ["kvaerno3 (PID) at rtol=1e-04, atol=1e-07"]


@pytest.mark.slow
def test_the_cheapest_setting_is_the_same_in_two_runs(tmp_path):
    # A small quick CartPole study, run twice: its timings differ between the runs, its
    # verdict must not.
    config = StudyConfig.default("CartPole", quick=True, horizon=20, batch=2, repeats=2, schedules=("recorded",))
    verdicts = []
    for run in range(2):
        result = run_study(config, progress=False)
        write_csv(result.rows, tmp_path / f"run{run}.csv")
        rows = read_csv(tmp_path / f"run{run}.csv")  # as a reader of the CSV reaches it
        verdicts.append([cheapest_at(rows, target) for target in VERDICT_TARGETS])
    assert verdicts[0][0] is not None, "the quick study reaches 1e-3"
    for first, second in zip(*verdicts):
        assert (first is None) == (second is None)
        if first is not None:
            assert (first["label"], first["setting"]) == (second["label"], second["setting"])
            assert first["measure"] == "vector_field_evaluations"


def _energy_study(**scene_kwargs):
    config = StudyConfig(
        scene="CartPole", scene_kwargs=scene_kwargs, sweeps=(SolverSweep("rk4", substeps=(4,)),),
        schedules=("zero",), horizon=50, batch=1, repeats=1, dense_points=2,
        initial_states=np.array([[0.0, 0.0, 0.2, 1.0]]),  # swinging: the damper has work to do
    )
    return run_study(config, progress=False)


@pytest.mark.slow
def test_energy_drift_only_for_scenes_that_conserve_energy(tmp_path):
    conservative, damped = _energy_study(), _energy_study(joint_damping=1.0)
    assert "energy" in conserved_quantities(make_scene("CartPole").physics)
    assert "energy" not in conserved_quantities(make_scene("CartPole", joint_damping=1.0).physics)
    # The damped cart-pole defines an energy, and it falls along the SciPy reference: a
    # drift reported for it would be the damper's work, not the solver's error.
    env = make_scene("CartPole", joint_damping=1.0)
    y0s = np.asarray(damped.record["initial_states"])
    with jax.enable_x64(True):
        ys = reference_trajectories(env.physics, y0s, np.zeros((50, 1)), float(env.dt))
        dissipated = float(env.physics.energy(y0s[0]) - env.physics.energy(ys[0, -1]))
    solver_drift = conservative.rows[0]["energy_drift"]
    assert math.isfinite(solver_drift) and solver_drift < 1e-6
    assert dissipated > 1e3 * solver_drift
    assert math.isnan(damped.rows[0]["energy_drift"])
    assert "energy_drift" not in damped.record["schedules"]["zero"].get("reference_drifts", {})
    write_csv(damped.rows, tmp_path / "damped.csv")
    assert read_csv_rows(tmp_path / "damped.csv")[0]["energy_drift"] == ""
    # The same columns but the energy drift's, which only the conservative row fills.
    damped_line, conservative_line = (format_table(result.rows).splitlines()[1] for result in (damped, conservative))
    assert len(conservative_line.split()) == len(damped_line.split()) + 1


@pytest.mark.parametrize("order", [1.0, 2.0, 4.0, 5.0])
@pytest.mark.parametrize("steps", [(0.02, 0.01, 0.005), (0.02 / 16, 0.02 / 64, 0.02 / 256), tuple(0.02 / 2**k for k in range(8))])
def test_order_guides_stay_inside_the_data(order, steps):
    # A line of the method's order, as a quick study's three steps or a full study's eight give it.
    points = [(h, 3.0 * h**order) for h in steps]
    x0, x1, y0, y1 = order_guide(points, order)
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    assert min(xs) <= x0 < x1 <= max(xs)
    assert min(ys) <= y0 < y1 <= max(ys)
    assert math.log(y1 / y0) / math.log(x1 / x0) == pytest.approx(order)


def test_no_order_guide_without_a_span():
    assert order_guide([(0.01, 1e-5)], 4.0) is None
    assert order_guide([(0.01, 1e-5), (0.02, 1e-5)], 4.0) is None
    assert order_guide([(0.01, 1e-5), (0.02, 1e-4)], math.nan) is None


def test_the_table_says_what_its_columns_are_and_flags_errors_inside_the_reference_floor():
    # The case: Dopri8 at 8.8e-14 against a reference floor of 5.3e-13.
    inside = _row("dopri8 (PID)", 1e-10, 8.8e-14, 200.0, 4e-3, reference_floor=5.3e-13, batch=8, horizon=100)
    outside = _row("tsit5 (PID)", 1e-6, 2.0e-7, 100.0, 2e-3, reference_floor=5.3e-13, batch=8, horizon=100)
    table = format_table([inside, outside])
    lines = table.splitlines()
    dopri8, = (line for line in lines if line.startswith("recorded  dopri8"))
    tsit5, = (line for line in lines if line.startswith("recorded  tsit5"))
    assert "8.80e-14*" in dopri8.split() and "2.00e-07" in tsit5.split() and "*" not in tsit5
    legend = "\n".join(lines[3:])
    assert "schedule recorded:" in legend and "random action" in legend
    assert "final time" in legend and "batch of 8" in legend and "100 env steps" in legend
    assert "5.3e-13" in legend and "reference's floor" in legend


def test_no_progress_bar_is_drawn_into_a_file(tmp_path):
    from lerax_like.analysis.study._study import _progress_bar

    pytest.importorskip("tqdm")
    with open(tmp_path / "log", "w") as log:
        with contextlib.redirect_stderr(log):
            bar = _progress_bar(3, True, "study")
            for _ in range(3):
                bar.update(1)
            bar.close()
    assert (tmp_path / "log").read_text() == ""
