"""The core knows nothing of the front ends: read off the package's source, not its behaviour.

Dependencies run one way: physics, integrate, gradients, env, scenes, spaces and analysis import
nothing from the Gymnasium layer (`lerax_like.gym`), the SB3 layer (`lerax_like.sb3`),
Gymnasium or SB3; and `env.py`, the step semantics every front end shares, names nothing
of Gymnasium (its spec, its attribute names, its keywords).
"""

import ast
import pathlib

import pytest

import lerax_like


PACKAGE = pathlib.Path(lerax_like.__file__).parent
CORE = ("physics", "integrate", "gradients", "env", "scenes", "spaces", "analysis")
FRONT_ENDS = ("lerax_like.gym", "lerax_like.sb3", "gymnasium", "stable_baselines3")


def _modules(name: str) -> list[pathlib.Path]:
    """The files of `lerax_like.<name>`, a module or a package."""
    package = PACKAGE / name
    if package.is_dir():
        return sorted(package.rglob("*.py"))
    return [PACKAGE / f"{name}.py"]


def _module_name(path: pathlib.Path, package: pathlib.Path) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: pathlib.Path, root: pathlib.Path = PACKAGE) -> set[str]:
    """Every module `path` (a file of the package at `root`) imports, anywhere in it (lazy
    imports inside functions too), by absolute name."""
    module = _module_name(path, root)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module
            names.add(prefix)
            # `from . import gym` imports the module `lerax_like.gym`.
            names.update(f"{prefix}.{alias.name}" for alias in node.names)
    return names


def _is_front_end(name: str) -> bool:
    return any(name == front or name.startswith(front + ".") for front in FRONT_ENDS)


@pytest.mark.parametrize("name", CORE)
def test_the_core_imports_no_front_end(name):
    files = _modules(name)
    assert files and all(path.exists() for path in files), name
    offending = {str(path.relative_to(PACKAGE)): sorted(filter(_is_front_end, imported(path))) for path in files}
    assert not {path: names for path, names in offending.items() if names}


def test_the_import_reader_sees_front_end_imports(tmp_path):
    # The reader itself, on a module that does import the front ends in each way.
    scenes = tmp_path / "lerax_like" / "scenes"
    scenes.mkdir(parents=True)
    probe = scenes / "probe.py"
    probe.write_text(
        "from ..gym import SPECS\nfrom .. import sb3\nimport gymnasium.spaces\n"
        "def later():\n    from ..gym._specs import GymSpec\n"
    )
    names = imported(probe, tmp_path / "lerax_like")
    assert {"lerax_like.gym", "lerax_like.sb3", "gymnasium.spaces", "lerax_like.gym._specs"} <= names
    assert all(_is_front_end(name) for name in ("lerax_like.gym", "lerax_like.sb3", "gymnasium.spaces"))
    assert not _is_front_end("lerax_like.gymnax") and not _is_front_end("lerax_like.gradients")


def _names_and_strings(tree: ast.Module) -> list[str]:
    """Every identifier of `tree` and every string constant that is not a docstring."""
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docstrings.add(id(body[0].value))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            found.append(node.id)
        elif isinstance(node, ast.Attribute):
            found.append(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            found.append(node.name)
        elif isinstance(node, ast.arg):
            found.append(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:
            found.append(node.arg)
        elif isinstance(node, ast.alias):
            found.append(node.asname or node.name)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            found.append(node.value)
    return found


# Gymnasium's own names that the layer maps (its attribute names on its envs), and the
# keywords only the layer used.
GYMNASIUM_NAMES = ("gym", "masspole", "masscart", "render", "float32_start", "observation_dtype", "observation_before")


def test_env_names_nothing_of_gymnasium():
    names = _names_and_strings(ast.parse((PACKAGE / "env.py").read_text()))
    assert "AbstractEnv" in names and "advance" in names  # the reader reads the module
    offending = sorted({name for name in names for word in GYMNASIUM_NAMES if word in name.lower()})
    assert not offending


def test_the_layer_holds_the_gymnasium_declarations():
    # The layer's own names stay in it (`lerax_like.gym.GymnasiumSpec`), and no scene class holds one.
    assert not any(hasattr(scene, "gymnasium") for scene in lerax_like.SCENES.values())
    assert {spec.scene for spec in lerax_like.gym.SPECS.values()} <= set(lerax_like.SCENES.values())


def _module_level_imports(path: pathlib.Path) -> set[str]:
    """What `path` imports when it is imported: `imported` less the imports inside functions
    and under `if TYPE_CHECKING:`."""

    def runs_on_import(nodes):
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
                yield from runs_on_import(node.orelse)
                continue
            yield node
            yield from runs_on_import(ast.iter_child_nodes(node))

    module = _module_name(path, PACKAGE)
    package = (module if path.name == "__init__.py" else module.rpartition(".")[0]).split(".")
    names = set()
    for node in runs_on_import(ast.parse(path.read_text()).body):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                prefix = ".".join(package[: len(package) - (node.level - 1)] + ([node.module] if node.module else []))
            else:
                prefix = node.module
            names.add(prefix)
            names.update(f"{prefix}.{alias.name}" for alias in node.names)
    return names


@pytest.mark.slow  # 3.3 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_the_gradient_tools_sit_above_the_env_and_the_integrator_sits_below_them():
    # The adjoint is the integrator's configuration (`integrate/_adjoint.py`): the env and the
    # integrator import nothing of `lerax_like.gradients`, which uses them; the gradient tools
    # import nothing above themselves, nor SciPy, when the package is imported.
    below = [*_modules("integrate"), PACKAGE / "env.py"]
    assert {str(path.relative_to(PACKAGE)) for path in below if any(
        name == "lerax_like.gradients" or name.startswith("lerax_like.gradients.") for name in imported(path)
    )} == set()
    above = ("lerax_like.scenes", "lerax_like.analysis", "lerax_like.gym", "lerax_like.control", "scipy")
    offending = {
        str(path.relative_to(PACKAGE)): sorted(
            name for name in _module_level_imports(path) if any(name == a or name.startswith(a + ".") for a in above)
        )
        for path in _modules("gradients")
    }
    assert {path: names for path, names in offending.items() if names} == {}
    sensitivity = PACKAGE / "gradients" / "_sensitivity.py"
    assert "lerax_like.env" in _module_level_imports(sensitivity)
