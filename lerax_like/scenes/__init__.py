"""Scenes: a physics module, an integrator and a task (spaces, reward, termination).

`SCENES` is the registry that the command line, the studies, the Gymnasium layer and the
tests read: one line per scene below. A new scene is its physics module, its scene module
and one line here; the contract tests (`tests/test_scene_contract.py`) cover it from then
on, and `lerax-like study NAME` runs it.
"""

import importlib
from collections.abc import Mapping
from types import MappingProxyType

from ..env import AbstractEnv


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
    "rimless_wheel:RimlessWheel",
    "bouncing_ball:BouncingBall",
)


def _load(path: str) -> type[AbstractEnv]:
    module, name = path.split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


SCENES: Mapping[str, type[AbstractEnv]] = MappingProxyType(
    {scene.__name__: scene for scene in map(_load, _REGISTERED)}
)
"""Scene name -> scene class, as `lerax-like study NAME` and the tests spell it."""

globals().update(SCENES)

from .cartpole import AbstractCartPole as AbstractCartPole  # noqa: E402
from .mountain_car import AbstractMountainCar as AbstractMountainCar  # noqa: E402

__all__ = ["SCENES", "AbstractCartPole", "AbstractMountainCar", *SCENES]
