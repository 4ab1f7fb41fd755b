"""Rendering through Gymnasium's own classic-control renderers.

Each id's renderer is an instance of Gymnasium's env class, used only to draw: before
each frame its state and drawing parameters (track width, pole length, link lengths,
hill bounds) are copied from our scene (`GymSpec.render_sync`). pygame is optional
(the `render` extra), imported only when a frame is drawn.
"""

import importlib
from typing import Any

import numpy as np
from gymnasium.error import DependencyNotInstalled

from ._compiled import float64
from ._specs import GymSpec


def require_pygame() -> None:
    try:
        import pygame  # noqa: F401
    except ImportError as error:
        raise DependencyNotInstalled(
            'pygame is not installed, run `pip install "lerax_like[render]"` to render'
        ) from error


def _renderer_class(spec: GymSpec) -> type:
    module, name = spec.renderer.split(":")
    return getattr(importlib.import_module(module), name)


def render_fps(spec: GymSpec) -> int:
    return _renderer_class(spec).metadata["render_fps"]


def make_renderer(spec: GymSpec, render_mode: str) -> Any:
    require_pygame()
    return _renderer_class(spec)(render_mode=render_mode)


def draw(renderer: Any, spec: GymSpec, scene: Any, state: np.ndarray, action: np.ndarray | None):
    with float64():
        spec.render_sync(renderer, scene, np.array(state, dtype=np.float64), action)
    return renderer.render()


__all__ = ["draw", "make_renderer", "render_fps", "require_pygame"]
