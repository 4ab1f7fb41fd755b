"""The public surface is static: plain imports and an explicit `__all__`, every scene of the
package and every dynamics a scene uses at the top level, one name per concept (the names that
went still import, with a DeprecationWarning)."""

import ast
import importlib
import pathlib

import pytest

import lerax_like as ll


PACKAGE = pathlib.Path(ll.__file__).parent
PACKAGE_SCENES = {name: scene for name, scene in ll.SCENES.items() if scene.__module__.startswith("lerax_like.")}


def _imported_names(path: pathlib.Path) -> set[str]:
    """The names a module binds by plain `from ... import` (what a static reader sees)."""
    tree = ast.parse(path.read_text())
    return {alias.asname or alias.name for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) for alias in node.names}


def test_no_module_of_the_package_writes_its_names_through_globals():
    offending = [str(path.relative_to(PACKAGE)) for path in PACKAGE.rglob("*.py") if "globals()" in path.read_text()]
    assert not offending


@pytest.mark.parametrize("module", ["lerax_like", "lerax_like.scenes"])
def test_every_scene_of_the_package_is_imported_plainly_and_in_all(module):
    path = PACKAGE / ("__init__.py" if module == "lerax_like" else "scenes/__init__.py")
    names = _imported_names(path)
    exported = importlib.import_module(module).__all__
    for name, scene in PACKAGE_SCENES.items():
        assert name in names and name in exported, f"{module} does not import and export {name}"
        assert getattr(importlib.import_module(module), name) is scene


def test_every_dynamics_of_a_registered_scene_is_at_the_top_level():
    names = _imported_names(PACKAGE / "__init__.py")
    for scene in ll.SCENES.values():
        dynamics = type(scene().dynamics)
        if not dynamics.__module__.startswith("lerax_like."):
            continue  # a user's scene brings its own
        assert dynamics.__name__ in names and dynamics.__name__ in ll.__all__, dynamics.__name__
        assert getattr(ll, dynamics.__name__) is dynamics


def test_all_names_only_what_the_package_has():
    assert sorted(set(ll.__all__)) == sorted(ll.__all__)
    assert all(hasattr(ll, name) for name in ll.__all__)


@pytest.mark.parametrize(
    ("module", "old", "new"),
    [
        ("lerax_like", "SOLVER_PRESETS", lambda: ll.SOLVERS.names),
        ("lerax_like.integrate", "SOLVER_PRESETS", lambda: ll.SOLVERS.names),
        ("lerax_like", "GymnasiumSpec", lambda: ll.gym.GymnasiumSpec),
        ("lerax_like.gym", "GYMNASIUM_SPECS", lambda: ll.gym._specs.GYMNASIUM_SPECS),
        ("lerax_like.cli", "solver_from_spec", lambda: ll.integrate.solver_from_spec),
    ],
)
def test_a_name_that_went_still_imports_with_a_deprecation_warning(module, old, new):
    with pytest.warns(DeprecationWarning, match=rf"{module}\.{old} is deprecated: use "):
        value = getattr(importlib.import_module(module), old)
    assert value is new()
    with pytest.raises(AttributeError, match="has no attribute 'NO_SUCH_NAME'"):
        getattr(importlib.import_module(module), "NO_SUCH_NAME")


def test_the_package_uses_no_name_that_went():
    """Only the aliases themselves name them (so the package's own use never warns)."""
    aliases = {"__init__.py", "integrate/__init__.py", "gym/__init__.py", "gym/_specs.py", "cli.py"}
    for path in PACKAGE.rglob("*.py"):
        if str(path.relative_to(PACKAGE)) in aliases:
            continue
        text = path.read_text()
        assert not any(name in text for name in ("SOLVER_PRESETS", "GYMNASIUM_SPECS", "cli import solver_from_spec")), path
