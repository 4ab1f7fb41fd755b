"""Module attributes found by name at run time (a module `__getattr__`): names that went, kept
importable with a warning, and classes generated per Gymnasium id, found by their names."""

import importlib
import warnings
from collections.abc import Callable, Mapping
from typing import Any


def deprecated_names(module: str, names: dict[str, tuple[str, Callable[[], Any]]]) -> Callable[[str], Any]:
    """A module `__getattr__` for `module`: `names` maps each old name to (what to use instead,
    a function returning the object), so that an old import works and says what replaced it
    (a `DeprecationWarning`)."""

    def __getattr__(name: str) -> Any:
        if name not in names:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        instead, value = names[name]
        warnings.warn(f"{module}.{name} is deprecated: use {instead}", DeprecationWarning, stacklevel=2)
        return value()

    return __getattr__


def moved_names(module: str, places: dict[str, tuple[str, ...]]) -> Callable[[str], Any]:
    """A module `__getattr__` for `module`, whose names moved: `places` maps each new module to
    the names that now live in it. Each old import works and warns (a `DeprecationWarning`
    naming the new place)."""

    def lookup(new_module: str, name: str) -> Callable[[], Any]:
        return lambda: getattr(importlib.import_module(new_module), name)

    moved = {name: new_module for new_module, names in places.items() for name in names}
    return deprecated_names(module, {name: (f"{new}.{name}", lookup(new, name)) for name, new in moved.items()})


def generated_names(module: str, classes: Mapping[str, type]) -> Callable[[str], type]:
    """A module `__getattr__` for `module` that finds `classes` by name, as string entry points
    (`"lerax_like.gym.envs:CartPoleEnv"`) and pickle look them up."""

    def __getattr__(name: str) -> type:
        try:
            return classes[name]
        except KeyError:
            raise AttributeError(f"module {module!r} has no attribute {name!r}") from None

    return __getattr__


__all__ = ["deprecated_names", "generated_names", "moved_names"]
