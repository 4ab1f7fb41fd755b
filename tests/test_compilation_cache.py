"""The run's persistent compilation cache (tests/conftest.py): one temporary folder, made by
the process that starts the run, shared by its xdist workers, and gone when the run ends."""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import jax
import jax.numpy as jnp
import pytest


TESTS = pathlib.Path(__file__).resolve().parent

PROBE = '''
import json, os, pathlib
import jax, jax.numpy as jnp
import pytest


@pytest.mark.parametrize("copy", [0, 1])  # two tests, one for each worker
def test_probe(worker_id, copy):
    folder = jax.config.jax_compilation_cache_dir
    # A program this run compiles once and caches (any compile time, any size).
    jax.jit(lambda x: x * 3.0 - 1.0)(jnp.arange(5.0)).block_until_ready()
    entries = sorted(path.name for path in pathlib.Path(folder).iterdir())
    record = {"folder": folder, "variable": os.environ["JAX_COMPILATION_CACHE_DIR"], "entries": entries}
    (pathlib.Path(os.environ["PROBE_OUT"]) / f"{worker_id}.json").write_text(json.dumps(record))
'''


def test_this_run_compiles_into_a_temporary_folder_of_its_own():
    folder = pathlib.Path(jax.config.jax_compilation_cache_dir)
    assert folder.is_dir() and folder.name.startswith("lerax_like-tests-jax-cache-")
    assert folder.parent == pathlib.Path(tempfile.gettempdir())
    assert not folder.is_relative_to(pathlib.Path.home())
    # The processes that tests start read JAX's own variables.
    assert os.environ["JAX_COMPILATION_CACHE_DIR"] == str(folder)
    assert jax.config.jax_persistent_cache_min_compile_time_secs == 0
    before = set(folder.iterdir())
    # A program no other test compiles: too quick for JAX's default threshold of one second.
    jax.jit(lambda x: jnp.cumsum(x) * 7.0 + 11.0)(jnp.arange(13.0)).block_until_ready()
    assert any(path.name.startswith("jit__lambda") for path in set(folder.iterdir()) - before)


# Three processes (a controller and two workers), each importing JAX through the conftest.
@pytest.mark.slow
def test_the_workers_share_the_controllers_folder_and_it_is_removed_at_the_end(tmp_path):
    probe = tmp_path / "probe"
    probe.mkdir()
    for name in ("conftest.py", "timings.py"):  # the conftest and the plugin it imports
        shutil.copy(TESTS / name, probe / name)
    (probe / "test_probe.py").write_text(PROBE)
    out = tmp_path / "out"
    out.mkdir()
    # -c /dev/null and no PYTEST_ADDOPTS: none of the project's options nor the caller's (a
    # --timings=FILE there would have the probe's controller empty the caller's FILE); two workers (xdist's `load` sends one test to each).
    env = {name: value for name, value in os.environ.items() if name != "PYTEST_ADDOPTS"} | {"PROBE_OUT": str(out)}
    completed = subprocess.run(
        [sys.executable, "-m", "pytest", "-c", os.devnull, "--rootdir", str(probe), "-p", "no:cacheprovider",
         "-n", "2", "-q", "test_probe.py"],
        cwd=probe, capture_output=True, text=True, timeout=600, env=env,
    )
    assert completed.returncode == 0, completed.stdout + completed.stderr
    records = [json.loads(path.read_text()) for path in sorted(out.glob("*.json"))]
    assert {path.stem for path in out.glob("*.json")} == {"gw0", "gw1"}, completed.stdout
    folders = {record["folder"] for record in records}
    assert len(folders) == 1 and folders == {record["variable"] for record in records}
    folder = pathlib.Path(folders.pop())
    # Not this run's folder: the probe's run made its own ...
    assert folder != pathlib.Path(jax.config.jax_compilation_cache_dir)
    assert folder.parent == pathlib.Path(tempfile.gettempdir())
    # ... both workers wrote into it ...
    assert all(any(name.startswith("jit__lambda") for name in record["entries"]) for record in records)
    # ... and it was removed when the run ended.
    assert not folder.exists()
