"""The documentation builds: the API reference from the docstrings and the notebooks (mkdocs.yml)."""

import importlib.util
import os
import pathlib
import subprocess
import sys

import pytest

import lerax_like

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
    for name in ("AbstractEnv", "rollout"):
        assert f'id="lerax_like.{name}"' in envs, f"{name} missing from the API reference"
    # Every registered scene, and its physics, has its reference.
    physics = (site / "api" / "physics" / "index.html").read_text()
    for name, scene in lerax_like.SCENES.items():
        assert f'id="{scene.__module__}.{name}"' in envs, f"scene {name} missing from the API reference"
        dynamics = type(scene().dynamics)
        assert f'id="{dynamics.__module__}.{dynamics.__name__}"' in physics, f"{dynamics.__name__} missing"
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert (site / "notebooks" / notebook.stem / "index.html").exists(), f"{notebook.name} not rendered"



def test_every_notebook_is_in_the_documentation_nav():
    nav = (ROOT / "mkdocs.yml").read_text()
    missing = [path.name for path in (ROOT / "notebooks").glob("*.ipynb") if f"notebooks/{path.name}" not in nav]
    assert not missing, f"add to mkdocs.yml's nav: {missing}"
