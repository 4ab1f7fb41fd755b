"""The scenes a study can name: one line per scene.

A scene plugs into `lerax-like study NAME` (and `rollout`, and the benchmark) by adding
its constructor here. Everything the study needs is read from the env itself: random
initial states from `initial`, a recorded action schedule from `action_space`, the
physical input from `physical_input`, energy and momentum from `dynamics` when it has
them. Scenes whose dynamics are stiff are listed in `STIFF_SCENES`, so that the SciPy
reference uses Radau instead of DOP853.

The SciPy reference integrates the vector field alone: a scene that clips or wraps its
state after each step (a `project` override) is measured against the unclipped motion,
which is the right reference only while the projection stays inactive.
"""

from collections.abc import Callable

from ..env import AbstractEnv
from ..scenes import (
    Acrobot,
    CartPole,
    CartPoleContinuous,
    DoubleCartPole,
    MountainCar,
    MountainCarContinuous,
    NLinkPendulum,
    Pendulum,
    VanDerPol,
)


SCENES: dict[str, Callable[..., AbstractEnv]] = {
    "CartPole": CartPole,
    "CartPoleContinuous": CartPoleContinuous,
    "Pendulum": Pendulum,
    "Acrobot": Acrobot,
    "MountainCar": MountainCar,
    "MountainCarContinuous": MountainCarContinuous,
    "VanDerPol": VanDerPol,
    "DoubleCartPole": DoubleCartPole,
    "NLinkPendulum": NLinkPendulum,
}
"""Scene name -> constructor (keyword arguments only), as `lerax-like study NAME` spells it."""

STIFF_SCENES: frozenset[str] = frozenset({"VanDerPol"})
"""Scenes whose reference is computed with an implicit method (SciPy's Radau)."""


def make_scene(name: str, **kwargs) -> AbstractEnv:
    """The env registered as `name`, built with `kwargs` (its constructor's keywords)."""
    try:
        constructor = SCENES[name]
    except KeyError:
        raise ValueError(f"unknown scene {name!r}; known scenes: {', '.join(SCENES)}") from None
    return constructor(**kwargs)
