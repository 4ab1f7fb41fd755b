"""The registry of scenes, `SCENES`: what the command line, the studies, the Gymnasium layer
and the tests read. A scene joins it with `register_scene` (the package's scenes as they are
defined, a user's or a test's wherever it is)."""

from collections.abc import Mapping
from types import MappingProxyType
from typing import TypeVar

from ..env import AbstractEnv
from ._unit_action import AbstractUnitActionEnv

_SCENES: dict[str, type[AbstractEnv]] = {}

SCENES: Mapping[str, type[AbstractEnv]] = MappingProxyType(_SCENES)
"""Scene name -> scene class, as `lerax-like study NAME` and the tests spell it (read-only:
`register_scene` adds to it)."""


def _abstract_parts(scene: type) -> list[str]:
    """What `scene` leaves abstract: methods, and Equinox's abstract fields and class variables."""
    parts: set[str] = set(getattr(scene, "__abstractmethods__", ()))
    parts |= set(getattr(scene, "__abstractvars__", ())) | set(getattr(scene, "__abstractclassvars__", ()))
    if (
        issubclass(scene, AbstractUnitActionEnv)
        and scene.physical_input is AbstractUnitActionEnv.physical_input
        and scene.action_scale is None
    ):
        parts.add("action_scale (or physical_input)")
    return sorted(parts)


def is_abstract_scene(scene: type) -> bool:
    """Whether `scene` leaves anything abstract (so it can be subclassed but not built)."""
    return bool(_abstract_parts(scene))


_Scene = TypeVar("_Scene", bound=type[AbstractEnv])


def register_scene(scene: _Scene) -> _Scene:
    """Add `scene` to `SCENES` under its class name, and return it (so it serves as a decorator).

    The scene must be a concrete (`@typing.final`) subclass of `AbstractEnv` that implements
    every abstract method; a name already registered for another class is refused.
    Registering the same class again changes nothing.
    """
    if not (isinstance(scene, type) and issubclass(scene, AbstractEnv)):
        raise TypeError(f"scene must be a subclass of lerax_like.AbstractEnv, got {scene!r}")
    name = scene.__name__
    missing = _abstract_parts(scene)
    if missing:
        raise TypeError(f"scene {name} is abstract: it does not declare {', '.join(missing)}")
    if not vars(scene).get("__final__", False):  # its own mark, not a final base's
        raise TypeError(f"scene {name} must be marked @typing.final (a concrete scene is final)")
    registered = _SCENES.get(name)
    if registered is not None and registered is not scene:
        raise ValueError(
            f"a scene named {name} is already registered ({registered.__module__}.{name}); "
            f"give {scene.__module__}.{name} another class name"
        )
    _SCENES[name] = scene
    return scene
