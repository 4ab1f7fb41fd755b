"""The documentation builds: the API reference from the docstrings and the notebooks (mkdocs.yml)."""

import importlib.util
import os
import pathlib
import re
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
        if not scene.__module__.startswith("lerax_like."):
            continue  # registered by a test module, not part of the package's reference
        assert f'id="{scene.__module__}.{name}"' in envs, f"scene {name} missing from the API reference"
        dynamics = type(scene().dynamics)
        assert f'id="{dynamics.__module__}.{dynamics.__name__}"' in physics, f"{dynamics.__name__} missing"
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert (site / "notebooks" / notebook.stem / "index.html").exists(), f"{notebook.name} not rendered"



def test_every_notebook_is_in_the_documentation_nav():
    nav = (ROOT / "mkdocs.yml").read_text()
    missing = [path.name for path in (ROOT / "notebooks").glob("*.ipynb") if f"notebooks/{path.name}" not in nav]
    assert not missing, f"add to mkdocs.yml's nav: {missing}"


# -- The page "What a new scene must declare", run as a contributor would read it ----------

NEW_SCENE_PAGE = ROOT / "docs" / "new_scene.md"


# A block that the tests do not run says so, and why, in an HTML comment on the line before its
# fence (not shown on the rendered page): `<!-- not run by tests/test_docs.py: the reason -->`.
NOT_RUN = "<!-- not run by tests/test_docs.py:"


def page_code(page: pathlib.Path) -> str:
    """The page's Python code blocks, in order, as one script (those marked `NOT_RUN` left out)."""
    blocks = re.findall(r"^([^\n]*)\n```python\n(.*?)^```", page.read_text(), flags=re.S | re.M)
    assert blocks, f"{page.name} has no python code block"
    return "\n".join(code for before, code in blocks if not before.startswith(NOT_RUN))


def _run(arguments, cwd, pythonpath=(), environment=None):
    # This checkout's lerax_like first, whatever the current directory. No PYTEST_ADDOPTS: the
    # caller's options (a --timings=FILE, which a run's first process empties) are not the page's.
    paths = [*map(str, pythonpath), str(ROOT), os.environ.get("PYTHONPATH", "")]
    inherited = {name: value for name, value in os.environ.items() if name != "PYTEST_ADDOPTS"}
    env = {**inherited, "JAX_PLATFORMS": "cpu", "PYTHONPATH": os.pathsep.join(paths), **(environment or {})}
    return subprocess.run([sys.executable, *arguments], cwd=cwd, capture_output=True, text=True, timeout=900, env=env)


@pytest.mark.slow
def test_the_new_scene_page_builds_a_working_scene(tmp_path):
    # In a process of its own, so that the page's scene joins no registry that this
    # process's other tests read. Checked beyond the page's own lines: the registry,
    # errors by name, a jitted step, and a gradient through a rollout.
    checks = """
import equinox as eqx
import numpy as np

scene = ll.SCENES["PointMass"]
assert scene is PointMass and scene.__final__
for bad, name in (({"mass": -1.0}, "mass"), ({"force_mag": float("nan")}, "force_mag"), ({"mass": "heavy"}, "mass")):
    try:
        ll.make(scene, **bad)
    except (TypeError, ValueError) as error:
        assert str(error).startswith(name), error
    else:
        raise AssertionError(f"{bad} was accepted")
env = scene()
state, _, _ = env.reset(key=jr.key(0))
step = eqx.filter_jit(env.step)
for i in range(5):
    state, observation, reward, terminated, truncated, info = step(state, jnp.array([1.0]), key=jr.key(i))
assert bool(info["solver_ok"]) and int(state.steps) == 5

def final_speed(mass):
    ys, _ = ll.rollout(ll.make(scene, mass=mass), env.reset(key=jr.key(0))[0], jnp.ones((10, 1)))
    return ys[-1, 1]

# x_dot grows by force_mag * t / mass: d/dm at t = 0.5 s is -0.5 / m**2.
gradient = float(jax.grad(final_speed)(2.0))
assert abs(gradient + 0.5 / 4.0) < 1e-5, gradient
print("ok")
"""
    script = tmp_path / "new_scene.py"
    script.write_text(page_code(NEW_SCENE_PAGE) + "\n" + checks)
    completed = _run([str(script)], cwd=tmp_path)
    assert completed.returncode == 0 and completed.stdout.strip().endswith("ok"), completed.stderr[-4000:]


@pytest.mark.slow
def test_the_new_scene_page_passes_the_scene_contract(tmp_path):
    # The page's code as a pytest plugin: imported before collection, so the contract tests,
    # parametrised over lerax_like.SCENES, include its scene.
    (tmp_path / "new_scene_page.py").write_text(page_code(NEW_SCENE_PAGE))
    completed = _run(
        ["-m", "pytest", "-p", "new_scene_page", "tests/test_scene_contract.py", "-k", "PointMass",
         "-n", "0", "-q", "-p", "no:cacheprovider"],
        cwd=ROOT, pythonpath=[tmp_path],
    )
    assert completed.returncode == 0, completed.stdout[-4000:]
    passed = re.search(r"(\d+) passed", completed.stdout)
    assert passed and int(passed.group(1)) >= 6, completed.stdout[-2000:]
    assert "failed" not in completed.stdout and "error" not in completed.stdout.lower().split("passed")[-1]


def test_the_new_scene_page_is_in_the_documentation_nav():
    assert "new_scene.md" in (ROOT / "mkdocs.yml").read_text()


# -- Every other page's Python code, and the README's, run as a reader would paste it -------

CODE_PAGES = sorted(
    page for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]
    if page != NEW_SCENE_PAGE and "```python" in page.read_text() and page_code(page).strip()
)


@pytest.mark.slow
@pytest.mark.parametrize("page", CODE_PAGES, ids=lambda page: page.name)
def test_the_pages_code_runs(page, tmp_path):
    # In a process of its own from an empty folder, with HOME there, so that what a page writes
    # (a cache folder under ~) lands in the test's folder.
    script = tmp_path / f"page_{page.stem}.py"  # not gymnasium.py, which would shadow gymnasium
    script.write_text(page_code(page) + "\nprint('ok')\n")
    completed = _run([str(script)], cwd=tmp_path, environment={"HOME": str(tmp_path)})
    assert completed.returncode == 0 and completed.stdout.strip().endswith("ok"), completed.stderr[-4000:]


def test_every_page_with_code_is_run_and_in_the_nav():
    nav = (ROOT / "mkdocs.yml").read_text()
    pages = {page.name for page in (ROOT / "docs").glob("*.md")}
    assert {page.name for page in CODE_PAGES} >= {"README.md", "gymnasium.md", "performance.md"}
    assert not [name for name in pages if f" {name}" not in nav], "every docs page belongs in mkdocs.yml's nav"
    for page in CODE_PAGES:
        for reason in re.findall(re.escape(NOT_RUN) + r"(.*?)-->", page.read_text()):
            assert len(reason.split()) >= 3, f"{page.name}: a block not run says why in words: {reason!r}"


@pytest.mark.slow  # 2.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_the_readme_is_a_door():
    # Diffrax's README is 82 lines and Gymnasium's 87; results, tables and limits live in docs/.
    lines = len((ROOT / "README.md").read_text().splitlines())
    assert lines <= 250, f"README.md has {lines} lines: move sections to docs/ pages"
