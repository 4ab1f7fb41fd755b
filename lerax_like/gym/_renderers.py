"""Which picture draws which scene: `RENDERERS`, keyed by scene or dynamics class.

A renderer is a function `(scene, state, action) -> (height, width, 3) uint8 array`
(`lerax_like.gym._pictures` holds the package's, drawn with NumPy alone). A scene is
drawn by the renderer of its own class or, failing that, of its dynamics' class (the
nearest along each class's bases): a picture of the physics serves every scene built on
it, and a scene whose task has something to show (a target, a wall) has its own.

A scene added outside the package (a user's, a contributor's) adds its picture with
`register_renderer`; `tests/test_render.py` draws every registered scene, and fails
naming the scene that has none. (Behind their Gymnasium ids, the scenes standing for
Gymnasium's envs are drawn by Gymnasium's own renderers: `lerax_like.gym._render`.)
"""

from collections.abc import Callable, Mapping
from types import MappingProxyType

import numpy as np

from ..env import AbstractEnv
from ..physics import (
    AcrobotDynamics,
    CartChainDynamics,
    CartPoleDynamics,
    MountainCarDynamics,
    NLinkPendulumDynamics,
    PendulumDynamics,
    PlanarQuadrotorDynamics,
    VanDerPolDynamics,
)
from ..physics.compass_gait import CompassGaitDynamics
from ..physics.rimless_wheel import RimlessWheelDynamics
from ..physics.rolling_disk import RollingDiskDynamics
from ..physics.simplest_walker import SimplestWalkerDynamics
from ..physics.sliding_block import SlidingBlockDynamics
from ..scenes import SCENES
from . import _pictures as pictures
from ._compiled import float64


Renderer = Callable[[AbstractEnv, np.ndarray, "np.ndarray | None"], np.ndarray]

_RENDERERS: dict[type, Renderer] = {
    CartPoleDynamics: pictures.cart_pole,
    PendulumDynamics: pictures.pendulum,
    AcrobotDynamics: pictures.acrobot,
    MountainCarDynamics: pictures.mountain_car,
    CartChainDynamics: pictures.cart_chain,
    NLinkPendulumDynamics: pictures.n_link_pendulum,
    PlanarQuadrotorDynamics: pictures.planar_quadrotor,
    RimlessWheelDynamics: pictures.rimless_wheel,
    SimplestWalkerDynamics: pictures.simplest_walker,
    CompassGaitDynamics: pictures.compass_gait,
    SlidingBlockDynamics: pictures.sliding_block,
    RollingDiskDynamics: pictures.rolling_disk,
    VanDerPolDynamics: pictures.van_der_pol,
    SCENES["BouncingBall"]: pictures.bouncing_ball,
}

RENDERERS: Mapping[type, Renderer] = MappingProxyType(_RENDERERS)
"""Scene or dynamics class -> the function that draws it (read-only: `register_renderer` adds)."""


def register_renderer(cls: type, renderer: Renderer | None = None):
    """Draw the scenes of scene class `cls`, or the scenes whose dynamics are of class
    `cls`, with `renderer(scene, state, action)`, which returns an `(height, width, 3)`
    uint8 array (`state` is the scene's state as a NumPy float64 array, `action` the last
    action or None after a reset). Returns `renderer`; without it, a decorator.
    """
    if not isinstance(cls, type):
        raise TypeError(f"cls must be a scene or dynamics class, got {cls!r}")

    def register(renderer: Renderer) -> Renderer:
        if not callable(renderer):
            raise TypeError(f"renderer must be a function (scene, state, action) -> array, got {renderer!r}")
        _RENDERERS[cls] = renderer
        return renderer

    return register if renderer is None else register(renderer)


def renderer_for(scene: AbstractEnv) -> Renderer:
    """The renderer of `scene`: its class's, else its dynamics class's (nearest base first)."""
    dynamics = getattr(scene, "dynamics", None)
    for cls in (*type(scene).__mro__, *type(dynamics).__mro__):
        if cls in _RENDERERS:
            return _RENDERERS[cls]
    name, physics = type(scene).__name__, type(dynamics).__name__
    raise LookupError(
        f"no renderer draws scene {name} (dynamics {physics}): add one with "
        f"lerax_like.gym.register_renderer({name}, draw) or ({physics}, draw), where draw(scene, state, action) "
        "returns an (height, width, 3) uint8 array (see docs/scenes.md)"
    )


def render_frame(scene: AbstractEnv, state, action=None) -> np.ndarray:
    """The picture of `scene` in `state` (its own layout) after `action` (None: no force
    drawn): an `(height, width, 3)` uint8 array, drawn with NumPy alone."""
    with float64():
        frame = renderer_for(scene)(scene, np.array(state, dtype=np.float64), action)
    frame = np.asarray(frame)
    if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        raise TypeError(
            f"the renderer of {type(scene).__name__} must return an (height, width, 3) uint8 array, "
            f"got {frame.dtype} of shape {frame.shape}"
        )
    return frame
