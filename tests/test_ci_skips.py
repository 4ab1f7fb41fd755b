"""In CI a test skipped for something the test extra installs fails; elsewhere it stays a skip.

Runs pytest on probe tests in a temporary folder holding this suite's conftest.py and a
pyproject.toml whose `test` extra lists made-up distributions, once with `CI=true` (as CI
runs .ci/run) and once without `CI`, and reads the outcomes pytest reports.
"""

import os
import pathlib
import shutil
import subprocess
import sys

import pytest


# Two pytest processes, each importing JAX through the conftest: 5.6 s of CPU together
# (measured under load: 23 s of wall time), so out of the quick loop.
pytestmark = pytest.mark.slow

CONFTEST = pathlib.Path(__file__).resolve().parent / "conftest.py"

PYPROJECT = """
[project]
name = "probe-package"
version = "0"
dependencies = ["a-core-dependency"]

[project.optional-dependencies]
docs = ["a-docs-tool"]
test = ["probe_package[docs]", "a-test-tool"]
bench = ["a-bench-peer"]
"""

MODULE_LEVEL = '''
import pytest

pytest.importorskip("a_test_tool")


def test_never_collected():
    pass
'''

IN_TESTS = '''
import pytest


def test_imports_a_test_tool():
    pytest.importorskip("a_test_tool.submodule")


def test_imports_what_an_included_extra_lists():
    pytest.importorskip("a_docs_tool")


def test_imports_a_core_dependency():
    pytest.importorskip("a_core_dependency")


@pytest.mark.skipif(True, reason="needs the docs extra (pip install -e '.[docs]')")
def test_hints_at_an_included_extra():
    pass


@pytest.mark.skipif(True, reason="the console script is not installed (pip install -e .)")
def test_hints_at_the_package():
    pass


def test_imports_what_only_another_extra_lists():
    pytest.importorskip("a_bench_peer")


@pytest.mark.skipif(True, reason="needs the bench extra (pip install -e '.[bench]')")
def test_hints_at_another_extra():
    pass


def test_that_does_not_apply():
    pytest.skip("a constant force conserves nothing")
'''

MISSING_FROM_CI = {
    "test_imports_a_test_tool", "test_imports_what_an_included_extra_lists", "test_imports_a_core_dependency",
    "test_hints_at_an_included_extra", "test_hints_at_the_package",
}
SKIPPED_IN_CI = {"test_imports_what_only_another_extra_lists", "test_hints_at_another_extra", "test_that_does_not_apply"}


def _run(folder, ci):
    """pytest's exit status on both probe files, the names of the probe tests (or the
    module) per outcome, and its output."""
    env = {name: value for name, value in os.environ.items() if name not in ("CI", "PYTEST_ADDOPTS")}
    if ci:
        env["CI"] = "true"
    # -c /dev/null, and no PYTEST_ADDOPTS: none of the project's options (no xdist, no nbmake) nor the caller's; the probe folder is
    # the root, so its pyproject.toml is the one read. A collection error would stop the
    # run before the tests (pytest's default); -rA lists every outcome.
    completed = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", os.devnull, "--rootdir", str(folder), "-p", "no:cacheprovider",
         "--continue-on-collection-errors", "-q", "-rA", "test_module_level.py", "test_in_tests.py"],
        cwd=folder, capture_output=True, text=True, timeout=300, env=env,
    )
    outcomes = {}
    for line in completed.stdout.splitlines():
        outcome, _, rest = line.partition(" ")
        if outcome in ("PASSED", "FAILED", "ERROR", "SKIPPED"):
            # "FAILED test_x.py::name - why", "ERROR test_x.py - why", "SKIPPED [1] test_x.py:12: why"
            where = rest.split(" - ")[0]
            outcomes.setdefault(outcome, []).append(where.split("::")[-1].strip())
    return completed.returncode, outcomes, completed.stdout


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The probes run once without CI and once with CI=true (two pytest processes)."""
    folder = tmp_path_factory.mktemp("probes")
    shutil.copy(CONFTEST, folder / "conftest.py")
    (folder / "pyproject.toml").write_text(PYPROJECT)
    (folder / "test_module_level.py").write_text(MODULE_LEVEL)
    (folder / "test_in_tests.py").write_text(IN_TESTS)
    return {"local": _run(folder, ci=False), "ci": _run(folder, ci=True)}


def test_every_such_skip_stays_a_skip_outside_ci(runs):
    returncode, outcomes, stdout = runs["local"]
    assert returncode == 0, stdout
    # Each probe test, and the module skipped at collection.
    assert set(outcomes) == {"SKIPPED"} and len(outcomes["SKIPPED"]) == len(MISSING_FROM_CI | SKIPPED_IN_CI) + 1, stdout


def test_in_ci_a_skip_for_what_the_test_extra_installs_fails(runs):
    returncode, outcomes, stdout = runs["ci"]
    assert returncode == 1, stdout
    # An importorskip fails in the test's call, a skipif mark in its setup (an error).
    failed = set(outcomes.get("FAILED", [])) | set(outcomes.get("ERROR", []))
    assert failed - {"test_module_level.py"} == MISSING_FROM_CI, stdout
    assert "should have installed this" in stdout and "a_test_tool" in stdout
    # Whatever the test extra leaves out, and a test that does not apply, stay skips.
    assert len(outcomes.get("SKIPPED", [])) == len(SKIPPED_IN_CI), stdout
    for reason in ("a_bench_peer", "'.[bench]'", "conserves nothing"):
        assert any(reason in line for line in stdout.splitlines() if line.startswith("SKIPPED")), (reason, stdout)


def test_in_ci_a_module_skipped_at_collection_fails(runs):
    returncode, outcomes, stdout = runs["ci"]
    assert "test_module_level.py" in outcomes.get("ERROR", []), stdout
