"""The constructor a static type checker reads: a block written into each final class.

A type checker does not run `inspect.signature`, so each final dynamics, add-on and scene
of the package declares its `__init__` under `TYPE_CHECKING`, written from the signature
that `lerax_like._signatures` reads off the fields:

    python -m lerax_like._constructor_source           # lists the blocks not current
    python -m lerax_like._constructor_source --write   # rewrites them

`tests/test_signatures.py` fails on a block that is not current, so a field added to a
dynamics (or a scene, or an add-on) without rewriting the blocks is caught, and its
message is the block to paste.
"""

import ast
import inspect
import re
import sys
from typing import Any

from ._signatures import Constructor


BEGIN = "    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source"
END = "    # (end of the constructor written by python -m lerax_like._constructor_source)"
# What a block's annotations may name beyond its module's own names: imported in the block.
_IMPORTS = {
    "Sequence": "from collections.abc import Sequence",
    "Literal": "from typing import Literal",
    "diffrax": "import diffrax",
    "ArrayLike": "from lerax_like._types import ArrayLike",
    "ScalarLike": "from lerax_like._types import ScalarLike",
    "Integrator": "from lerax_like.integrate import Integrator",
}


def _default_text(default: Any) -> str:
    if isinstance(default, (bool, int, str, type(None))) or (isinstance(default, float) and default == default and abs(default) != float("inf")):
        return repr(default)
    if isinstance(default, tuple) and all(isinstance(item, (int, float)) for item in default):
        return repr(default)
    return "..."


def _import_order(name: str) -> tuple[int, str]:
    """Constants, then classes, then functions, as isort and ruff order a `from` import."""
    return (0 if name.isupper() else 1 if name[0].isupper() else 2, name)


def constructor_source(cls: type) -> str:
    """The block that declares `cls`'s constructor to a static type checker (its keywords, typed)."""
    parameters = list(inspect.signature(cls).parameters.values())
    names = {name for parameter in parameters for name in re.findall(r"[A-Za-z_]\w*", parameter.annotation)}
    lines = [BEGIN, *(f"        {line}" for name, line in _IMPORTS.items() if name in names and name not in vars(sys.modules[cls.__module__]))]
    lines += ["", "        def __init__(", "            self,", "            *,"]
    for parameter in parameters:
        default = "" if parameter.default is inspect.Parameter.empty else f" = {_default_text(parameter.default)}"
        lines.append(f"            {parameter.name}: {parameter.annotation}{default},")
    lines += ["        ) -> None: ...", END]
    return "\n".join(lines) + "\n"


def _class_lines(cls: type, source: list[str]) -> tuple[int, int | None]:
    """Where `cls`'s block is, `(begin, end)` (line indices), or `(after its docstring, None)`."""
    tree = ast.parse("".join(source))
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and node.name == cls.__name__:
            first = node.body[0]
            docstring = isinstance(first, ast.Expr) and isinstance(getattr(first, "value", None), ast.Constant)
            after = (first.end_lineno or first.lineno) if docstring else first.lineno - 1
            stop = node.end_lineno or len(source)
            for index in range(node.lineno, stop):
                if source[index].rstrip("\n") == BEGIN:
                    end = next(i for i in range(index, stop) if source[i].rstrip("\n") == END)
                    return index, end
            return after, None
    raise ValueError(f"class {cls.__name__} not found in its module's source")


def _module_source(cls: type) -> tuple[str, list[str]]:
    """The path of `cls`'s module and its lines as they are on disk now (not as imported)."""
    path = inspect.getsourcefile(cls)
    if path is None:
        raise ValueError(f"{cls.__name__} has no source file")
    with open(path) as file:
        return path, file.readlines()


def current(cls: type) -> bool:
    """Whether `cls`'s module declares its constructor as `constructor_source` writes it."""
    _, source = _module_source(cls)
    begin, end = _class_lines(cls, source)
    return end is not None and "".join(source[begin : end + 1]) == constructor_source(cls)


def write(cls: type) -> bool:
    """Write (or rewrite) `cls`'s block into its module's file; whether anything changed."""
    path, source = _module_source(cls)
    begin, end = _class_lines(cls, source)
    block = constructor_source(cls)
    if end is None:
        new = [*source[:begin], "\n", block, *source[begin:]]
    else:
        new = [*source[:begin], block, *source[end + 1 :]]
    if not any(line.startswith("from typing import") and "TYPE_CHECKING" in line for line in new):
        typing_line = next((i for i, line in enumerate(new) if re.fullmatch(r"from typing import [\w, ]+\n", line)), None)
        if typing_line is None:
            first = next(i for i, line in enumerate(new) if line.startswith(("import ", "from ")))
            new.insert(first, "from typing import TYPE_CHECKING\n")
        else:
            names = new[typing_line].removeprefix("from typing import ").strip().split(", ")
            new[typing_line] = f"from typing import {', '.join(sorted({*names, 'TYPE_CHECKING'}, key=_import_order))}\n"
    if new == source:
        return False
    with open(path, "w") as file:
        file.writelines(new)
    return True


def final_classes() -> list[type]:
    """The package's classes whose constructors are declared: its registered scenes, and every
    final dynamics, add-on and contact it defines."""
    import lerax_like

    from ._fields import AbstractParametrised

    found: list[type] = [scene for scene in lerax_like.SCENES.values() if scene.__module__.startswith("lerax_like.")]
    pending = [AbstractParametrised]
    while pending:
        klass = pending.pop()
        pending.extend(klass.__subclasses__())
        if (
            vars(klass).get("__final__", False)
            and klass.__module__.startswith("lerax_like.")
            and isinstance(inspect.getattr_static(klass, "__init__"), Constructor)  # not its own __init__
            and klass not in found
        ):
            found.append(klass)
    return found


def main(arguments: list[str]) -> int:
    """`python -m lerax_like._constructor_source [--write]`: list (or rewrite) the constructors not current."""
    stale = [cls for cls in final_classes() if not current(cls)]
    for cls in stale:
        if "--write" in arguments:
            write(cls)
        print(f"{cls.__module__}.{cls.__name__}" + (" written" if "--write" in arguments else " not current"))
    return 1 if stale and "--write" not in arguments else 0




__all__ = ["constructor_source", "current", "final_classes", "write"]


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
