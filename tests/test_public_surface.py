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


def test_the_names_that_went_are_gone():
    """The deprecated aliases of a 0.1.0 package went (the CHANGELOG says what replaced each)."""
    for module, old in [
        ("lerax_like", "SOLVER_PRESETS"),
        ("lerax_like.integrate", "SOLVER_PRESETS"),
        ("lerax_like", "GymnasiumSpec"),
        ("lerax_like.gym", "GYMNASIUM_SPECS"),
        ("lerax_like.cli", "solver_from_spec"),
        ("lerax_like", "parameter"),
    ]:
        assert not hasattr(importlib.import_module(module), old), (module, old)


@pytest.mark.slow  # 4.0 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_the_package_uses_no_name_that_went():
    """Only the Gymnasium layer's own table is still called by its name."""
    aliases = {"gym/_specs.py"}
    for path in PACKAGE.rglob("*.py"):
        if str(path.relative_to(PACKAGE)) in aliases:
            continue
        text = path.read_text()
        assert not any(name in text for name in ("SOLVER_PRESETS", "GYMNASIUM_SPECS", "cli import solver_from_spec")), path
