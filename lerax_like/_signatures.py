"""What a constructor takes, read from the fields: its signature, and the name nearest a misspelt one.

A dynamics (or an add-on) takes its fields. A scene takes its fields and, flat, the
parameters of its dynamics, the integrator's settings and its add-ons' parameters
(`CartPole(pole_mass=0.2, solver="rk4", joint_damping=0.5)`), as Gymnasium users pass them.
Nobody lists them by hand: `inspect.signature`, `help()` and an IDE's runtime
introspection read the signature built here from the fields (`Constructor`, the shared
`__init__`, computed per class on first use), and a static type checker reads the `__init__`
that `python -m lerax_like._constructor_source --write` writes from the same signature
into each final class, under `TYPE_CHECKING`.
"""

import ast
import dataclasses
import difflib
import inspect
import re
import sys
import textwrap
import types
from collections.abc import Callable, Iterable
from typing import Any


class Shown:
    """A default as a signature shows it (`CartPoleDynamics()`), where the value is built per instance."""

    def __init__(self, text: str):
        self.text = text

    def __repr__(self) -> str:
        return self.text


@dataclasses.dataclass(frozen=True)
class Keyword:
    """One keyword of a constructor: its name, default and type as source text (for the static checker)."""

    name: str
    default: Any
    annotation: str

    def parameter(self) -> inspect.Parameter:
        return inspect.Parameter(self.name, inspect.Parameter.KEYWORD_ONLY, default=self.default, annotation=self.annotation)


def describe(value: Any) -> str:
    """A short text for a default built by a factory: a module by its class, `(FloorAndWall(),)`."""
    if isinstance(value, tuple):
        inner = ", ".join(map(describe, value))
        return f"({inner},)" if len(value) == 1 else f"({inner})"
    if dataclasses.is_dataclass(value):
        return f"{type(value).__name__}()"
    return repr(value)


def annotation_text(owner: type | Callable, name: str) -> str:
    """The annotation of field (or argument) `name` as written in `owner`'s source, `"Any"` if none is found."""
    for klass in getattr(owner, "__mro__", (owner,)):
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(klass)))
        except (OSError, TypeError):
            continue
        node = tree.body[0]
        if isinstance(node, ast.ClassDef):
            for statement in node.body:
                if isinstance(statement, ast.AnnAssign) and getattr(statement.target, "id", None) == name:
                    return ast.unparse(statement.annotation)
        elif isinstance(node, ast.FunctionDef):
            for argument in (*node.args.args, *node.args.kwonlyargs):
                if argument.arg == name and argument.annotation is not None:
                    annotation = argument.annotation
                    if isinstance(annotation, ast.Constant) and isinstance(annotation.value, str):
                        return annotation.value
                    return ast.unparse(annotation)
    return "Any"


def field_keywords(cls: type) -> list[Keyword]:
    """The keywords of `cls`'s fields, defaults included, in declaration order."""
    keywords = []
    for field in dataclasses.fields(cls):
        if not field.init:
            continue
        metadata = field.metadata
        if metadata.get("default_from") is not None:
            doc = (metadata["default_from"].__doc__ or "computed from the fields before it").strip().splitlines()[0]
            default: Any = Shown(f"<{doc}>")
        elif field.default is not dataclasses.MISSING:
            default = field.default
        elif "factory" in metadata:
            default = Shown(f"{getattr(metadata['factory'], '__name__', 'dynamics')}()")
        elif "solver" in metadata:
            default = Shown(f"make_integrator({metadata['solver']!r})")
        elif field.default_factory is not dataclasses.MISSING:
            default = Shown(describe(field.default_factory()))
        else:
            default = inspect.Parameter.empty
        if metadata.get("parameter"):
            annotation = "ArrayLike | Sequence[float]" if metadata.get("shape") else "ScalarLike"
        else:
            annotation = annotation_text(cls, field.name)
        keywords.append(Keyword(field.name, default, annotation))
    return keywords


def scene_keywords(cls: type, integrator_keywords: Iterable[Keyword]) -> list[Keyword]:
    """A scene's keywords: its fields, then flat its dynamics' parameters, the integrator's
    settings, its add-ons' parameters (None: absent) and its aliases (None: not given)."""
    own = field_keywords(cls)
    names = {keyword.name for keyword in own}
    fields = {field.name: field for field in dataclasses.fields(cls)}
    flat: list[Keyword] = []
    factory = fields["dynamics"].metadata.get("factory") if "dynamics" in fields else None
    if factory is not None:
        fixed = getattr(factory, "keywords", {})  # a `functools.partial` fixes some
        for keyword in field_keywords(getattr(factory, "func", factory)):
            if keyword.name not in names:
                flat.append(dataclasses.replace(keyword, default=fixed.get(keyword.name, keyword.default)))
    if "integrator" in fields:
        solver = fields["integrator"].metadata.get("solver")
        for keyword in integrator_keywords:
            flat.append(keyword if keyword.name != "solver" or solver is None else dataclasses.replace(keyword, default=solver))
    for addon in getattr(cls, "addons", ()):
        for keyword in field_keywords(addon):
            if keyword.name not in names | {k.name for k in flat}:
                flat.append(Keyword(keyword.name, None, f"{keyword.annotation} | None"))
    known = {keyword.name: keyword for keyword in own + flat}
    for alias, target in getattr(cls, "aliases", ()):
        flat.append(Keyword(alias, None, f"{known[target].annotation} | None" if target in known else "Any"))
    return own + flat


_SIGNATURES: dict[type, inspect.Signature] = {}


class Constructor:
    """The `__init__` of a family of classes (all dynamics, all scenes), one function whose
    signature is, per class, what `keywords(cls)` reads off its fields.

    Equinox's `help()` and `inspect.signature(cls)` read `inspect.signature(cls.__init__)`, so
    the signature is given there: `cls.__init__` is this function seen from `cls`, built on
    first use (fields exist only once the class is made).
    """

    def __init__(self, function: Callable, keywords: Callable[[type], list[Keyword]]):
        self.function = function
        self.keywords = keywords
        self.__doc__ = function.__doc__

    def __get__(self, instance, owner: type):
        if instance is None:
            return _Unbound(self, owner)
        return types.MethodType(self.function, instance)

    def signature(self, owner: type) -> inspect.Signature:
        if owner not in _SIGNATURES:
            self_parameter = inspect.Parameter("self", inspect.Parameter.POSITIONAL_ONLY)
            _SIGNATURES[owner] = inspect.Signature([self_parameter, *(k.parameter() for k in self.keywords(owner))])
        return _SIGNATURES[owner]


class _Unbound:
    """`cls.__init__`: callable with the instance first, with `cls`'s signature."""

    __name__ = "__init__"

    def __init__(self, constructor: Constructor, owner: type):
        self._constructor = constructor
        self._owner = owner
        self.__doc__ = constructor.__doc__
        self.__qualname__ = f"{owner.__qualname__}.__init__"

    def __call__(self, instance, *arguments, **keywords):
        return self._constructor.function(instance, *arguments, **keywords)

    @property
    def __annotations__(self) -> dict:  # read by equinox when it makes a subclass
        return {}

    @property
    def __signature__(self) -> inspect.Signature:
        return self._constructor.signature(self._owner)


def refuse_unknown(cls: type, given: Iterable[str], known: Iterable[str]) -> None:
    """Refuse keywords `cls` does not take, naming for each the closest it does take."""
    known = sorted(known)
    unknown = sorted(set(given) - set(known))
    if not unknown:
        return
    hints = []
    for name in unknown:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hints.append(f"{name} (did you mean {close[0]}?)" if close else name)
    raise TypeError(f"{cls.__name__} got unknown keyword(s) {', '.join(hints)}; it takes {', '.join(known)}")


__all__ = ["Constructor", "Keyword", "Shown", "annotation_text", "field_keywords", "refuse_unknown", "scene_keywords"]
