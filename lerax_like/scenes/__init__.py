"""Scenes: a physics module, an integrator and a task (spaces, reward, termination).

`SCENES` is the registry that the command line, the studies, the Gymnasium layer and the
tests read. Each scene of the package registers itself where it is defined
(`@register_scene`), in the order of the imports below; a scene defined elsewhere (a user's,
a test's) joins the same way. The contract tests (`tests/test_scene_contract.py`) cover every
registered scene, and `lerax-like study NAME` runs it. `make` builds one from flat keywords.
"""

from ._registry import SCENES as SCENES, is_abstract_scene as is_abstract_scene, register_scene as register_scene
from ._unit_action import AbstractUnitActionEnv as AbstractUnitActionEnv
from .cartpole import (
    AbstractCartPole as AbstractCartPole,
    CartPole as CartPole,
    CartPoleContinuous as CartPoleContinuous,
)
from .pendulum import Pendulum as Pendulum
from .acrobot import Acrobot as Acrobot
from .mountain_car import (
    AbstractMountainCar as AbstractMountainCar,
    MountainCar as MountainCar,
    MountainCarContinuous as MountainCarContinuous,
)
from .van_der_pol import VanDerPol as VanDerPol
from .double_cartpole import DoubleCartPole as DoubleCartPole
from .n_link_pendulum import NLinkPendulum as NLinkPendulum
from .planar_quadrotor import PlanarQuadrotor as PlanarQuadrotor
from .bouncing_ball import BouncingBall as BouncingBall
from .rimless_wheel import RimlessWheel as RimlessWheel
from .simplest_walker import SimplestWalker as SimplestWalker
from .compass_gait import CompassGait as CompassGait
from .sliding_block import SlidingBlock as SlidingBlock
from .rolling_disk import RollingDisk as RollingDisk
from ._make import make as make

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
    "RollingDisk",
    "SimplestWalker",
    "SlidingBlock",
    "VanDerPol",
    "is_abstract_scene",
    "make",
    "register_scene",
]
