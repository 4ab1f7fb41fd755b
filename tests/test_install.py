"""The install lines that the README and docs/install.md show, run as written with `pip install --dry-run`.

The package is on no index: a line that names `lerax_like[...]` fails for every user, while
`".[extra]"` from a clone's root works. Each line is resolved by pip (network or the machine's
package mirror), and the CPU route for PyTorch is checked for what it promises: a CPU build,
no CUDA libraries, and kept by the `sb3` extra installed after it.
"""

import importlib.metadata
import importlib.util
import json
import os
import pathlib
import re
import shlex
import subprocess
import sys
import tomllib

import pytest

import lerax_like

ROOT = pathlib.Path(__file__).resolve().parent.parent
CPU_INDEX = "https://download.pytorch.org/whl/cpu"


def install_lines(page: pathlib.Path) -> list[str]:
    """The `python -m pip install ...` lines of the page's bash blocks, without a chained
    command (`&& lerax-like study ...`) or a trailing comment."""
    lines = []
    for block in re.findall(r"^```bash\n(.*?)^```", page.read_text(), flags=re.S | re.M):
        for line in block.splitlines():
            command = line.split("&&")[0].split(" #")[0].strip()
            if command.startswith("python -m pip install"):
                lines.append(command)
    return lines


README_LINES = install_lines(ROOT / "README.md")
LINES = sorted(set(README_LINES) | set(install_lines(ROOT / "docs" / "install.md")))


def test_the_readme_shows_install_lines_that_work_from_a_clone():
    assert README_LINES, "README.md shows no install line"
    for line in LINES:
        assert "lerax_like[" not in line and "lerax-like[" not in line, f"{line!r}: the package is on no index"
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    shown = {extra for line in README_LINES for extra in re.findall(r'"\.\[(\w+)\]"', line)}
    assert shown <= set(extras), f"the README installs extras that pyproject.toml lacks: {shown - set(extras)}"
    assert {"study", "test", "sb3"} <= shown
    assert any(CPU_INDEX in line for line in README_LINES), "the README states PyTorch's CPU route for sb3"


def _dry_run(line: str, tmp_path: pathlib.Path, *extra: str) -> dict:
    arguments = shlex.split(line)[3:]  # after `python -m pip`
    report = tmp_path / "report.json"
    # The clone's own metadata built with the installed setuptools: an isolated build would
    # first install setuptools into a fresh environment, for every line (a minute on a loaded machine).
    isolation = [] if importlib.util.find_spec("setuptools") is None else ["--no-build-isolation"]
    command = [sys.executable, "-m", "pip", *arguments, "--dry-run", "--quiet", "--report", str(report),
               "--retries", "1", "--timeout", "30", *isolation, *extra]
    completed = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert completed.returncode == 0, f"{line!r} does not resolve:\n{completed.stderr[-3000:]}"
    return json.loads(report.read_text())


def _installed(report: dict) -> dict[str, str]:
    return {item["metadata"]["name"].lower(): item["metadata"]["version"] for item in report["install"]}


@pytest.mark.slow
@pytest.mark.parametrize("line", LINES)
def test_each_install_line_resolves(line, tmp_path):
    if CPU_INDEX in line:
        # From scratch, as on a fresh machine: the CPU build, and no CUDA library.
        installed = _installed(_dry_run(line, tmp_path, "--ignore-installed", "--no-deps"))
        assert installed["torch"].endswith("+cpu"), installed
        return
    installed = _installed(_dry_run(line, tmp_path))
    assert not [name for name in installed if name.startswith("nvidia")], f"{line!r} brings CUDA: {installed}"
    torch_build = _version("torch")
    if "[sb3]" in line and torch_build and torch_build.endswith("+cpu"):
        # Installed after the CPU build, the extra keeps it.
        assert "torch" not in installed, f"{line!r} replaces the CPU build {torch_build}: {installed['torch']}"


def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def test_version_is_the_packages_metadata():
    assert lerax_like.__version__ == tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_a_source_tree_imports_without_the_package_installed():
    # A clone on PYTHONPATH, never installed: importlib.metadata knows no lerax_like. The
    # installed metadata is hidden by making the lookup fail as it does for a clone.
    script = (
        "import importlib.metadata as m\n"
        "real = m.version\n"
        "def version(name):\n"
        "    if name == 'lerax_like':\n"
        "        raise m.PackageNotFoundError(name)\n"
        "    return real(name)\n"
        "m.version = version\n"
        "import lerax_like\n"
        "print(lerax_like.__file__, lerax_like.__version__)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    assert result.returncode == 0, result.stderr
    path, version = result.stdout.split()
    assert pathlib.Path(path).resolve().parent == ROOT / "lerax_like"
    assert version == "0+unknown"


def _editable_install() -> bool:
    """Whether the environment's lerax_like is an editable install (pip's direct_url.json says so).

    Every distribution of that name is asked: run from the clone, the first one found on the path
    is the clone's own `lerax_like.egg-info` (the build writes it there), which pip's record is not in.
    """
    for distribution in importlib.metadata.distributions(name="lerax_like"):
        direct_url = distribution.read_text("direct_url.json")
        if direct_url and json.loads(direct_url).get("dir_info", {}).get("editable"):
            return True
    return False


def test_the_readme_installs_in_a_mode_that_type_checkers_follow():
    # setuptools' default editable install is an import hook, which static tools cannot follow;
    # strict mode is a tree of links on a path in a .pth file, which they read.
    (line,) = [line for line in README_LINES if line.startswith("python -m pip install -e")]
    assert "--config-settings editable_mode=strict" in line
    assert line in (ROOT / ".ci" / "run").read_text()


@pytest.mark.skipif(not _editable_install(), reason="lerax_like is not installed in editable mode here (a source "
                    "tree or a plain install): there is no editable install to resolve")
@pytest.mark.slow  # 6.2 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_basedpyright_resolves_the_editable_install_from_outside_the_clone(tmp_path):
    pytest.importorskip("basedpyright")
    assert ROOT not in tmp_path.parents
    (tmp_path / "script.py").write_text(
        "import lerax_like\n\nenv = lerax_like.CartPole(integrator='tsit5')\nreveal_type(env)\n"
    )
    completed = subprocess.run(
        [sys.executable, "-m", "basedpyright", "--pythonpath", sys.executable, "--outputjson", "script.py"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )
    report = json.loads(completed.stdout)
    problems = [d for d in report["generalDiagnostics"] if d["severity"] in ("error", "warning")]
    assert not problems, problems
    revealed = [d["message"] for d in report["generalDiagnostics"] if d["severity"] == "information"]
    assert revealed == ['Type of "env" is "CartPole"'], revealed
