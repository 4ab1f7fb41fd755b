"""The documentation builds: the API reference from the docstrings and the notebooks (mkdocs.yml)."""

import importlib.util
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent
MISSING = [
    name for name in ("mkdocs", "mkdocstrings_handlers.python", "mkdocs_jupyter", "material")
    if importlib.util.find_spec(name.split(".")[0]) is None
]


@pytest.mark.slow
@pytest.mark.skipif(bool(MISSING), reason=f"needs the docs extra (pip install -e '.[docs]'); missing {MISSING}")
def test_documentation_builds_strictly(tmp_path):
    # --strict turns every warning (a broken link, a docstring mkdocstrings cannot resolve,
    # a notebook that fails to convert) into a failure.
    completed = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, capture_output=True, text=True, timeout=600, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"},
    )
    assert completed.returncode == 0, completed.stderr[-4000:]
    site = tmp_path / "site"
    envs = (site / "api" / "envs" / "index.html").read_text()
    for name in ("CartPole", "AbstractEnv", "rollout"):
        assert f'id="lerax_like.{name}"' in envs, f"{name} missing from the API reference"
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert (site / "notebooks" / notebook.stem / "index.html").exists(), f"{notebook.name} not rendered"

