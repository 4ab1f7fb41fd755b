"""A study says why: a failed setting's reason in the table, the CSV, the JSON and the figure;
a fitted order that disagrees with the declared one flagged; a bad tableau refused by name."""

import json
import textwrap
from typing import ClassVar

import diffrax
import numpy as np
import pytest

from lerax_like.analysis import SolverSweep, StudyConfig, run_study
from lerax_like.analysis.convergence import convergence_orders
from lerax_like.analysis.figures import plot_work_precision
from lerax_like.analysis.study import read_csv, write_study
from lerax_like.analysis.tables import format_orders, format_table
from lerax_like.analysis.verdict import order_disagreements
from lerax_like.cli import main


class MisdeclaredEuler(diffrax.AbstractERK):
    """Euler's method in two stages (the second unused) that declares order 2: a wrong claim."""

    tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
        c=np.array([1.0]), b_sol=np.array([1.0, 0.0]), b_error=np.zeros(2), a_lower=(np.array([1.0]),)
    )
    interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation.from_k

    def order(self, terms):
        return 2


@pytest.fixture(scope="module")
def failing_study(tmp_path_factory):
    # Heun's embedded pair at rtol 1e-12 needs thousands of steps per env step of 0.05 s,
    # more than the 64 allowed here: a setting that fails by its step budget. Euler's steps,
    # fitted, give order 1 against the declared 2 (a small swing; its errors, 2e-3 to 1e-2,
    # are fitted below a ceiling of 0.1).
    config = StudyConfig(
        scene="Pendulum",
        sweeps=(
            SolverSweep(MisdeclaredEuler(), substeps=(8, 16, 32)),
            SolverSweep("heun", tolerances=((1e-3, 1e-6), (1e-12, 1e-15))),
        ),
        schedules=("zero",), initial_states=[[0.1, 0.0]], horizon=10, repeats=1, max_steps=64, fit_ceiling=0.1,
    )
    result = run_study(config, progress=False)
    out = tmp_path_factory.mktemp("study")
    paths = write_study(result, out)
    return result, paths


@pytest.mark.slow
def test_a_failed_setting_says_why_in_the_table_csv_json_and_figure(failing_study):
    result, paths = failing_study
    failed = [row for row in result.rows if not row["solver_ok"]]
    assert [(row["label"], row["rtol"]) for row in failed] == [("heun (PID)", 1e-12)]
    assert failed[0]["failure"].startswith("step budget exhausted (64 solver steps per env step) at env step 0")
    assert all(row["failure"] == "" for row in result.rows if row["solver_ok"])
    table = format_table(result.rows)
    line = next(line for line in table.splitlines() if "heun (PID)" in line and "1e-12" in line)
    assert "failed" in line and "step budget exhausted" in line
    csv_rows = read_csv(paths["csv"])
    assert [row["failure"] for row in csv_rows if not row["solver_ok"]] == [failed[0]["failure"]]
    record = json.loads(open(paths["json"]).read())
    assert record["failures"][0]["failure"] == failed[0]["failure"]
    # The figure marks it (not dropped): its record, and a marker of the failed setting.
    assert record["figure"]["failed"] == [{"label": "heun (PID)", "setting": "rtol=1e-12, atol=1e-15",
                                           "failure": failed[0]["failure"]}]
    figure = plot_work_precision(csv_rows)
    markers = [line for axis in figure.axes for line in axis.get_lines() if line.get_gid() == "failed"]
    assert len(markers) == 1 and markers[0].get_marker() == "X"
    assert any("step budget exhausted" in text.get_text() for text in figure.texts)


@pytest.mark.slow
def test_a_misdeclared_order_is_flagged_in_the_orders_and_the_verdict(failing_study):
    result, paths = failing_study
    (entry,) = [e for e in result.convergence_orders() if e["solver"] == "MisdeclaredEuler"]
    assert entry["method_order"] == 2 and entry["points"] >= 2, entry
    assert abs(entry["order"] - 1) < 0.1, entry
    assert entry["disagrees"] is True
    assert "!! disagrees with the declared order 2 by" in format_orders([entry])
    record = json.loads(open(paths["json"]).read())
    (verdict,) = record["order_disagreements"]
    assert verdict.startswith(f"MisdeclaredEuler (zero actions): fitted order {entry['order']:.2f} over")
    assert "declared 2: the method or its declared order is wrong" in verdict


@pytest.mark.parametrize("slope, flagged", [(2.0, False), (1.75, False), (2.25, False), (1.65, True), (2.4, True)])
def test_the_order_flag_is_a_distance_of_more_than_0_3(slope, flagged):
    # Errors that fall exactly as h**slope, from a method that declares order 2.
    rows = [
        {"scene": "S", "schedule": "zero", "solver": "m", "controller": "ConstantStepSize", "order": 2.0,
         "dt": h, "error": 1e-3 * (h / 0.01) ** slope, "reference_floor": 1e-14}
        for h in (0.01, 0.005, 0.0025)
    ]
    (entry,) = convergence_orders(rows)
    assert entry["order"] == pytest.approx(slope) and entry["disagrees"] is flagged
    assert ("!! disagrees" in format_orders([entry])) is flagged
    assert len(order_disagreements([entry])) == int(flagged)


BROKEN_MODULE = textwrap.dedent(
    """
    from typing import ClassVar

    import diffrax
    import numpy as np


    class Broken(diffrax.AbstractERK):
        # b_sol sums to 0.9: not even a first-order method
        tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
            c=np.array([0.5]), b_sol=np.array([0.4, 0.5]), b_error=np.zeros(2), a_lower=(np.array([0.5]),)
        )


    BROKEN = Broken()
    """
)


def test_a_bad_tableau_is_refused_by_name_before_any_solve(tmp_path, monkeypatch, capsys):
    (tmp_path / "broken_methods.py").write_text(BROKEN_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(SystemExit) as exit_info:
        main(["study", "CartPole", "--quick", "--solver", "broken_methods:BROKEN"])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err
    assert "solver 'broken_methods:BROKEN'" in error and "module 'broken_methods'" in error
    assert "broken_methods.py:10" in error and "b_sol must sum to 1" in error
    assert "Traceback" not in error


@pytest.mark.slow  # 4.1 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_substeps_set_the_sweep_from_the_command_line(capsys):
    from lerax_like.analysis.sweeps import default_sweeps, with_substeps

    assert main(["study", "CartPole", "--quick", "--substeps", "0", "4"]) == 2  # refused before any solve
    assert "substeps must be positive integers, got [0, 4]" in capsys.readouterr().err
    quick = default_sweeps(quick=True)
    sweeps = with_substeps(quick, [8, 2, 2])
    assert [s.substeps for s in sweeps if not s.adaptive] == [(2, 8), (2, 8)]
    assert [s.tolerances for s in sweeps if s.adaptive] == [s.tolerances for s in quick if s.adaptive]
