"""In CI a test skipped for a missing optional dependency fails; elsewhere it stays a skip.

Runs pytest on probe tests in a temporary folder with this suite's conftest.py, once with
`CI=true` (as CI runs .ci/run) and once without `CI`, and reads the outcomes pytest reports.
"""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest


CONFTEST = pathlib.Path(__file__).resolve().parent / "conftest.py"

MODULE_LEVEL = '''
import pytest

pytest.importorskip("a_module_that_no_extra_installs")


def test_never_collected():
    pass
'''

IN_TESTS = '''
import pytest


def test_imports_inside():
    pytest.importorskip("a_module_that_no_extra_installs")


@pytest.mark.skipif(True, reason="needs the docs extra (pip install -e '.[docs]')")
def test_marked_with_an_install_hint():
    pass


def test_that_does_not_apply():
    pytest.skip("a constant force conserves nothing")
'''


def _outcomes(folder, files, ci):
    env = {name: value for name, value in os.environ.items() if name != "CI"}
    if ci:
        env["CI"] = "true"
    # -c /dev/null: none of the project's addopts (no xdist, no nbmake); -rA lists every outcome.
    completed = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", os.devnull, "--rootdir", str(folder), "-p", "no:cacheprovider",
         "-q", "-rA", *files],
        cwd=folder, capture_output=True, text=True, timeout=120, env=env,
    )
    lines = completed.stdout.splitlines()
    outcomes = {}
    for line in lines:
        for outcome in ("PASSED", "FAILED", "ERROR", "SKIPPED"):
            if line.startswith(outcome + " "):
                outcomes.setdefault(outcome, []).append(line)
    return completed.returncode, outcomes, completed.stdout


@pytest.fixture
def probes(tmp_path):
    shutil.copy(CONFTEST, tmp_path / "conftest.py")
    (tmp_path / "test_module_level.py").write_text(MODULE_LEVEL)
    (tmp_path / "test_in_tests.py").write_text(IN_TESTS)
    return tmp_path


def test_a_missing_dependency_is_a_skip_outside_ci(probes):
    returncode, outcomes, stdout = _outcomes(probes, ["test_module_level.py", "test_in_tests.py"], ci=False)
    assert returncode == 0, stdout
    assert set(outcomes) == {"SKIPPED"} and len(outcomes["SKIPPED"]) == 4, stdout


def test_a_missing_dependency_fails_in_ci(probes):
    returncode, outcomes, stdout = _outcomes(probes, ["test_in_tests.py"], ci=True)
    assert returncode == 1, stdout
    assert any("test_imports_inside" in line for line in outcomes.get("FAILED", [])), stdout
    assert any("test_marked_with_an_install_hint" in line for line in outcomes.get("ERROR", [])), stdout
    # A skip because the test does not apply stays a skip.
    assert len(outcomes.get("SKIPPED", [])) == 1 and "conserves nothing" in outcomes["SKIPPED"][0], stdout
    assert "a_module_that_no_extra_installs" in stdout and "test extra" in stdout


def test_a_module_skipped_at_collection_fails_in_ci(probes):
    returncode, outcomes, stdout = _outcomes(probes, ["test_module_level.py"], ci=True)
    assert returncode != 0, stdout
    assert any("test_module_level.py" in line for line in outcomes.get("ERROR", [])), stdout
    assert "SKIPPED" not in outcomes, stdout
