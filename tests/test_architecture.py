"""The package's import rules, read off its source with `ast`.

No module under `lerax_like/` imports another module's private (underscored) name: a
private *module* is fine (`from ._fields import parameter`, `from . import _render`), a
private name is not (`from .report import _finish`): what a module shares, it makes public.
"""

import ast
import importlib.util
import pathlib

import pytest

import lerax_like


PACKAGE = pathlib.Path(lerax_like.__file__).resolve().parent


def _module_name(path: pathlib.Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _source_module(node: ast.ImportFrom, importer: str, is_package: bool) -> str:
    """The absolute name of the module that `from X import ...` reads, relative imports resolved."""
    if node.level == 0:
        return node.module
    # `from .x` in a package's __init__ is relative to the package itself.
    base = importer.split(".") if is_package else importer.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def private_name_imports(source: str, importer: str, is_package: bool = False) -> list[str]:
    """Every `from M import _name` in `source` (the text of module `importer`) where `_name`
    is a name defined in `M`, not a submodule of it."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            module = _source_module(node, importer, is_package)
            found += [
                f"line {node.lineno}: from {module} import {alias.name}"
                for alias in node.names
                if _is_private(alias.name) and not _is_module(f"{module}.{alias.name}")
            ]
    return found


def test_the_rule_tells_a_private_name_from_a_private_module():
    source = (
        "from .._fields import parameter\n"  # a private module, a public name: fine
        "from .. import _fields\n"  # a private module: fine
        "from ..gym import _render\n"  # a private submodule: fine
        "from .report import _finish\n"  # a private name: refused
        "from .._fields import _no_such_name as name\n"  # refused, whatever it is called here
        "from diffrax._root_finder import use_stepsize_tol\n"  # another package's public name: fine
        "from . import __version__\n"  # a dunder is not private
    )
    assert private_name_imports(source, "lerax_like.analysis.example") == [
        "line 4: from lerax_like.analysis.report import _finish",
        "line 5: from lerax_like._fields import _no_such_name",
    ]
    # In a package's __init__, `.` is the package itself.
    assert private_name_imports("from ._specs import _x\n", "lerax_like.gym", is_package=True) == [
        "line 1: from lerax_like.gym._specs import _x"
    ]


def _violations(paths) -> list[str]:
    return [
        f"{path.relative_to(PACKAGE.parent)} {line}"
        for path in sorted(paths)
        for line in private_name_imports(path.read_text(), _module_name(path), path.name == "__init__.py")
    ]


@pytest.mark.slow  # 3.7 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_no_module_imports_another_modules_private_name():
    found = _violations(PACKAGE.rglob("*.py"))
    assert not found, "private names imported across modules:\n" + "\n".join(found)
