"""benchmarks/RESULTS.md is what the recorded result files say, and the files are the runs' own."""

import hashlib
import json
import pathlib

import pytest

from benchmarks import BENCHMARKS, RESULTS
from benchmarks._report import render, write_results

ROOT = pathlib.Path(__file__).resolve().parent.parent


def test_results_md_is_regenerated_from_the_recorded_files():
    committed = (ROOT / "benchmarks" / "RESULTS.md").read_text()
    assert render(RESULTS, "results", quick=False) == committed, (
        "benchmarks/RESULTS.md differs from the result files: run `python -m benchmarks report`"
    )


def test_every_recorded_file_matches_its_run_record():
    records = sorted(RESULTS.glob("*.run.json"))
    assert records, "no run records under benchmarks/results/"
    recorded = set()
    for path in records:
        record = json.loads(path.read_text())
        assert record["benchmark"] in BENCHMARKS, f"{path.name}: unknown benchmark {record['benchmark']!r}"
        assert record["command"], f"{path.name} names no command"
        for name, digest in record["files"].items():
            file = RESULTS / name
            assert file.exists(), f"{path.name} records {name}, which is missing"
            assert hashlib.sha256(file.read_bytes()).hexdigest() == digest, f"{name} changed after {path.name}"
            recorded.add(name)
    # Every result file comes from a recorded run (the records and RESULTS.md aside).
    unrecorded = {
        path.name for path in RESULTS.iterdir()
        if path.is_file() and not path.name.endswith(".run.json")
    } - recorded
    assert not unrecorded, f"result files with no run record: {sorted(unrecorded)}"


def test_quick_results_go_to_their_own_folder(tmp_path, monkeypatch):
    import benchmarks
    import benchmarks._report as report

    monkeypatch.setattr(report, "results_dir", lambda quick: tmp_path / ("quick" if quick else "recorded"))
    path = write_results(quick=True)
    assert path == tmp_path / "quick" / "RESULTS.md"
    assert benchmarks.results_dir(True) == RESULTS / "quick" and benchmarks.results_dir(False) == RESULTS
    # With no result files every section says so rather than inventing a number.
    text = path.read_text()
    assert text.count("No results recorded yet") == len(BENCHMARKS)


@pytest.mark.slow  # 3.7 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_a_benchmark_whose_peer_is_missing_is_skipped_with_the_install_hint(monkeypatch, capsys):
    import dataclasses

    import benchmarks.__main__ as runner

    absent = dataclasses.replace(BENCHMARKS["throughput"], needs=(("no_such_peer_module", "pip install the-peer"),))
    monkeypatch.setitem(runner.BENCHMARKS, "throughput", absent)
    monkeypatch.setattr(runner.subprocess, "Popen", lambda *args, **kwargs: pytest.fail("a skipped benchmark ran"))
    outcome, seconds = runner.run_one("throughput", quick=True, options=[])
    assert outcome.startswith("skipped") and seconds == 0.0
    assert "no_such_peer_module (pip install the-peer)" in capsys.readouterr().out
