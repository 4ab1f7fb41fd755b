"""The constructor a static type checker reads: a block written into each final class.

A type checker does not run `inspect.signature`, so each final dynamics, add-on and scene
of the package declares its `__init__` under `TYPE_CHECKING`, written from the signature
that `lerax_like._signatures` reads off the fields:

    python -m lerax_like._constructor_source           # lists the blocks not current
    python -m lerax_like._constructor_source --write   # rewrites them

The keywords that constructors share are declared once, as TypedDicts in
`lerax_like._keywords` (written by the same command): the integrator's, each dynamics' and
each add-on's, and the fields an abstract scene (`AbstractCartPole`) declares for the final
scenes built on it. A dynamics takes its own as `**keywords: Unpack[...]` (PEP 692); a scene's
block lists only its own fields and aliases, with their defaults, and takes the rest (its
bases' fields, its dynamics', the integrator's and its add-ons' keywords) as one TypedDict
composed of those. The defaults of a keyword given by a TypedDict are not in the block (a
TypedDict has none): the runtime signature (`inspect.signature`, `help()`) shows them.

`tests/test_signatures.py` fails on a block or a `_keywords` module that is not current, so
a field added to a dynamics (or a scene, or an add-on) without rewriting them is caught,
and its message is the block to paste.
"""

import ast
import dataclasses
import inspect
import pathlib
import re
import sys
import textwrap
from typing import Any

from ._signatures import Constructor, field_keywords


BEGIN = "    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source"
END = "    # (end of the constructor written by python -m lerax_like._constructor_source)"
KEYWORDS_MODULE = "lerax_like._keywords"
# What annotations may name beyond a module's own names, and where each is imported from.
_IMPORTS = {
    "Sequence": "collections.abc",
    "Literal": "typing",
    "TypedDict": "typing",
    "Unpack": "typing",
    "diffrax": None,  # `import diffrax`
    "ArrayLike": "lerax_like._types",
    "ScalarLike": "lerax_like._types",
    "Integrator": "lerax_like.integrate",
}


@dataclasses.dataclass(frozen=True)
class Group:
    """Keywords that several constructors take, declared once as a TypedDict of `lerax_like._keywords`."""

    name: str
    doc: str | None  # None where the module's docstring says it (`<Class>Keywords`)
    keywords: tuple[tuple[str, str], ...]  # (name, annotation), its bases' first
    owner: type | None = None  # whose module the annotations' other names come from
    bases: tuple["Group", ...] = ()


def _default_text(default: Any) -> str:
    if isinstance(default, (bool, int, str, type(None))) or (isinstance(default, float) and default == default and abs(default) != float("inf")):
        return repr(default)
    if isinstance(default, tuple) and all(isinstance(item, (int, float)) for item in default):
        return repr(default)
    return "..."


def _import_order(name: str) -> tuple[int, str]:
    """Constants, then classes, then functions, as isort and ruff order a `from` import."""
    return (0 if name.isupper() else 1 if name[0].isupper() else 2, name)


def _import_lines(names: set[str], available: dict[str, Any], owners: tuple[type, ...] = ()) -> list[str]:
    """The imports of `names` that `available` (a module's namespace) lacks, one line per module:
    from `_IMPORTS`, or where the name comes from in the modules of `owners` (a dynamics class)."""
    modules: dict[str | None, set[str]] = {}
    for name, module in _IMPORTS.items():
        if name in names and name not in available:
            modules.setdefault(module, set()).add(name)
    for owner in owners:
        for name, value in vars(sys.modules[owner.__module__]).items():
            if name in names and name not in available and name not in _IMPORTS and isinstance(value, type):
                modules.setdefault(value.__module__, set()).add(name)
    lines = ["import diffrax"] if None in modules else []
    for module in (m for m in modules if m is not None):
        lines.append(f"from {module} import {', '.join(sorted(modules[module], key=_import_order))}")
    return lines


def _section(line: str) -> tuple[int, str]:
    """Where an import line goes, as isort orders them: the standard library, diffrax, the package."""
    return (0 if line.startswith(("from collections", "from typing")) else 1 if "diffrax" in line else 2, line)


def _sectioned(lines: list[str], indent: str = "") -> list[str]:
    """Import lines in isort's order, a blank line between sections."""
    out: list[str] = []
    for line in sorted(lines, key=_section):
        if out and _section(line)[0] != _section(out[-1].strip())[0]:
            out.append("")
        out.append(indent + line)
    return out


def _names(annotations) -> set[str]:
    return {name for annotation in annotations for name in re.findall(r"[A-Za-z_]\w*", annotation)}


def _package_scenes() -> list[type]:
    import lerax_like

    return [scene for scene in lerax_like.SCENES.values() if scene.__module__.startswith("lerax_like.")]


def _addons() -> list[type]:
    """The add-ons that the package's scenes take flat."""
    return sorted({addon for scene in _package_scenes() for addon in scene.addons}, key=lambda cls: cls.__name__)


def _takes_own_group(cls: type) -> bool:
    """Whether `cls` (a dynamics, say) takes its keywords as its own TypedDict: a final class of
    the package that is neither a scene nor an add-on and whose every keyword has a default."""
    return (
        cls.__module__.startswith("lerax_like.")
        and cls not in _package_scenes()
        and cls not in _addons()
        and isinstance(inspect.getattr_static(cls, "__init__"), Constructor)
        and all(keyword.default is not inspect.Parameter.empty for keyword in field_keywords(cls))
    )


def _scene_bases() -> list[type]:
    """The abstract scenes of the package that declare fields for the final scenes built on them."""
    bases = {
        base
        for scene in _package_scenes()
        for base in scene.__mro__[1:]
        if base.__module__.startswith("lerax_like.scenes") and dataclasses.is_dataclass(base) and dataclasses.fields(base)
    }
    return sorted(bases, key=lambda cls: cls.__name__)


def groups() -> list[Group]:
    """The TypedDicts of `lerax_like._keywords`: the integrator's, the fields an abstract scene
    declares for its final scenes, each add-on's (as a scene takes them: None, absent) and each
    dynamics' keywords."""
    from ._construct import integrator_keywords

    found = [
        Group(
            "IntegratorKeywords",
            "A scene's `integrator`, or the settings that build one with `make_integrator`.",
            (("integrator", "Integrator"), *((keyword.name, keyword.annotation) for keyword in integrator_keywords())),
        )
    ]
    integrator = {key for key, _ in found[0].keywords}
    for base in _scene_bases():
        found.append(
            Group(
                f"{base.__name__}Keywords",
                f"The fields `{base.__name__}` declares, once, for the final scenes built on it.",
                tuple((k.name, k.annotation) for k in field_keywords(base) if k.name not in integrator),
                base,
            )
        )
    # The event budget that every located add-on (contacts, friction) takes, declared once.
    budget = Group("EventBudgetKeywords", "The located events (impacts, stick-slip switches) allowed per env step.", (("max_events", "int | None"),))
    if any("max_events" in {f.name for f in dataclasses.fields(addon)} for addon in _addons()):
        found.append(budget)
    for addon in _addons():
        keys = tuple((keyword.name, f"{keyword.annotation} | None") for keyword in field_keywords(addon))
        bases = (budget,) if set(budget.keywords) <= set(keys) else ()
        keys = (*(key for base in bases for key in base.keywords), *(key for key in keys if key not in budget.keywords or not bases))
        found.append(Group(f"{addon.__name__}Keywords", None, keys, bases=bases))
    for cls in sorted((cls for cls in final_classes() if _takes_own_group(cls)), key=lambda cls: cls.__name__):
        found.append(
            Group(
                f"{cls.__name__}Keywords",
                None,
                tuple((keyword.name, keyword.annotation) for keyword in field_keywords(cls)),
            )
        )
    return found


def _groups_of(cls: type, parameters: dict[str, inspect.Parameter]) -> list[Group]:
    """The groups whose keywords `cls`'s signature takes, each with the same annotation: its abstract
    bases' fields, its dynamics', the integrator's and its add-ons' (a group that does not fit is
    listed keyword by keyword)."""
    by_name = {group.name: group for group in groups()}
    fields = {field.name: field for field in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else {}
    wanted = [f"{base.__name__}Keywords" for base in cls.__mro__[1:]]
    factory = fields["dynamics"].metadata.get("factory") if "dynamics" in fields else None
    if factory is not None:
        wanted.append(f"{getattr(factory, 'func', factory).__name__}Keywords")
    if "integrator" in fields:
        wanted.append("IntegratorKeywords")
    wanted += [f"{addon.__name__}Keywords" for addon in getattr(cls, "addons", ())]
    return [
        by_name[name]
        for name in wanted
        if name in by_name
        and all(key in parameters and parameters[key].annotation == annotation for key, annotation in by_name[name].keywords)
    ]


def constructor_source(cls: type) -> str:
    """The block that declares `cls`'s constructor to a static type checker (its keywords, typed)."""
    available = vars(sys.modules[cls.__module__])
    if _takes_own_group(cls):
        group = f"{cls.__name__}Keywords"
        imports = [*_import_lines({"Unpack"}, available), f"from {KEYWORDS_MODULE} import {group}"]
        lines = [BEGIN, *_sectioned(imports, "        "), ""]
        lines += [f"        def __init__(self, **keywords: Unpack[{group}]) -> None: ...", END]
        return "\n".join(lines) + "\n"
    parameters = dict(inspect.signature(cls).parameters)
    shared = _groups_of(cls, parameters)
    covered = {key for group in shared for key, _ in group.keywords}
    own = [parameter for name, parameter in parameters.items() if name not in covered]
    names = _names(parameter.annotation for parameter in own) | ({"Unpack"} if shared else set())
    imports = _import_lines(names, available)
    if shared:
        imports.append(f"from {KEYWORDS_MODULE} import {', '.join(sorted(group.name for group in shared))}")
    lines = [BEGIN, *_sectioned(imports, "        ")]
    if len(shared) > 1:
        # PEP 692 takes one TypedDict for `**keywords`: the groups composed.
        lines += ["", f"        class _Keywords({', '.join(group.name for group in shared)}, total=False): ..."]
    lines += ["", "        def __init__(", "            self,", "            *,"]
    for parameter in own:
        default = "" if parameter.default is inspect.Parameter.empty else f" = {_default_text(parameter.default)}"
        lines.append(f"            {parameter.name}: {parameter.annotation}{default},")
    if shared:
        lines.append(f"            **keywords: Unpack[{'_Keywords' if len(shared) > 1 else shared[0].name}],")
    lines += ["        ) -> None: ...", END]
    return "\n".join(lines) + "\n"


def keywords_module_source() -> str:
    """The source of `lerax_like._keywords`: every group, a TypedDict of its keywords (none required)."""
    found = groups()
    lines = [
        '"""The keywords that constructors share, declared once for a static type checker (PEP 692).',
        "",
        "Written by `python -m lerax_like._constructor_source --write` from the signatures read off",
        "the fields (`lerax_like._signatures`); a dynamics takes its own as `**keywords`, and a scene",
        "those of its abstract bases' fields, its dynamics, the integrator and its add-ons, composed.",
        "`<Class>Keywords` are the keywords of that dynamics, or of that add-on as a scene takes them",
        "flat (None: absent, unless given). A TypedDict holds no defaults: `inspect.signature` shows them.",
        '"""',
        "",
        *_sectioned(
            _import_lines(
                _names(a for group in found for _, a in group.keywords) | {"TypedDict"},
                {},
                tuple(group.owner for group in found if group.owner is not None),
            )
        ),
    ]
    for group in found:
        inherited = {key for base in group.bases for key in base.keywords}
        bases = ", ".join([*(base.name for base in group.bases)] or ["TypedDict"])
        own = [f"    {key}: {annotation}" for key, annotation in group.keywords if (key, annotation) not in inherited]
        lines += ["", "", f"class {group.name}({bases}, total=False):" + ("" if own or group.doc else " ...")]
        lines += [f'    """{group.doc}"""', ""] if group.doc else []
        lines += own
    names = textwrap.wrap(", ".join(f'"{group.name}"' for group in found), 100)
    lines += ["", "", "__all__ = [", *(f"    {line}" for line in names), "]"]
    return "\n".join(lines) + "\n"


def _keywords_path() -> pathlib.Path:
    return pathlib.Path(__file__).with_name("_keywords.py")


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


def keywords_module_current() -> bool:
    """Whether `lerax_like/_keywords.py` is as `keywords_module_source` writes it."""
    path = _keywords_path()
    return path.exists() and path.read_text() == keywords_module_source()


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
    from ._fields import AbstractParametrised

    found: list[type] = _package_scenes()
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
    writing = "--write" in arguments
    stale = [] if keywords_module_current() else [KEYWORDS_MODULE]
    if stale and writing:
        _keywords_path().write_text(keywords_module_source())
    for cls in final_classes():
        if not current(cls):
            if writing:
                write(cls)
            stale.append(f"{cls.__module__}.{cls.__name__}")
    for name in stale:
        print(name + (" written" if writing else " not current"))
    return 1 if stale and not writing else 0


__all__ = ["Group", "constructor_source", "current", "final_classes", "groups", "keywords_module_current", "keywords_module_source", "write"]


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
