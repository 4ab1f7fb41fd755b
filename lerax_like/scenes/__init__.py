"""Scenes: a physics module, an integrator and a task (spaces, reward, termination).

`SCENES` is the registry that the command line, the studies, the Gymnasium layer and the
tests read. The package's scenes are its lines below; a scene defined elsewhere (a user's,
a test's) joins with `register_scene`. The contract tests (`tests/test_scene_contract.py`)
cover every registered scene, and `lerax-like study NAME` runs it.
"""

import importlib
from collections.abc import Mapping
from types import MappingProxyType

from ..env import AbstractEnv
from ._unit_action import AbstractUnitActionEnv as AbstractUnitActionEnv


_REGISTERED = (
    "cartpole:CartPole",
    "cartpole:CartPoleContinuous",
    "pendulum:Pendulum",
    "acrobot:Acrobot",
    "mountain_car:MountainCar",
    "mountain_car:MountainCarContinuous",
    "van_der_pol:VanDerPol",
    "double_cartpole:DoubleCartPole",
    "n_link_pendulum:NLinkPendulum",
    "planar_quadrotor:PlanarQuadrotor",
    "bouncing_ball:BouncingBall",
    "rimless_wheel:RimlessWheel",
    "simplest_walker:SimplestWalker",
    "compass_gait:CompassGait",
    "sliding_block:SlidingBlock",
)


def _load(path: str) -> type[AbstractEnv]:
    module, name = path.split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


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


def register_scene(scene: type[AbstractEnv]) -> type[AbstractEnv]:
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


for _path in _REGISTERED:
    register_scene(_load(_path))
del _path

# The same classes by plain import, so that tools see them (tests/test_public_surface.py
# checks that every scene of `_REGISTERED` is here and in `__all__`).
from .acrobot import Acrobot as Acrobot  # noqa: E402
from .bouncing_ball import BouncingBall as BouncingBall  # noqa: E402
from .cartpole import (  # noqa: E402
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .double_cartpole import DoubleCartPole as DoubleCartPole  # noqa: E402
from .mountain_car import (  # noqa: E402
    AbstractMountainCar as AbstractMountainCar,
    MountainCar as MountainCar,
    MountainCarContinuous as MountainCarContinuous,
)
from .n_link_pendulum import NLinkPendulum as NLinkPendulum  # noqa: E402
from .pendulum import Pendulum as Pendulum  # noqa: E402
from .planar_quadrotor import PlanarQuadrotor as PlanarQuadrotor  # noqa: E402
from .rimless_wheel import RimlessWheel as RimlessWheel  # noqa: E402
from .compass_gait import CompassGait as CompassGait  # noqa: E402
from .simplest_walker import SimplestWalker as SimplestWalker  # noqa: E402
from .sliding_block import SlidingBlock as SlidingBlock  # noqa: E402
from .van_der_pol import VanDerPol as VanDerPol  # noqa: E402

__all__ = [
    "SCENES",
    "AbstractCartPole",
    "AbstractMountainCar",
    "AbstractUnitActionEnv",
    "Acrobot",
    "BouncingBall",
    "CartPole",
    "CartPoleContinuous",
    "CompassGait",
    "DoubleCartPole",
    "MountainCar",
    "MountainCarContinuous",
    "NLinkPendulum",
    "Pendulum",
    "PlanarQuadrotor",
    "RimlessWheel",
    "SimplestWalker",
    "SlidingBlock",
    "VanDerPol",
    "is_abstract_scene",
    "register_scene",
]
