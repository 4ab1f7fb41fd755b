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


def tile(frames: list[np.ndarray]) -> np.ndarray:
    """The frames (all of one shape, `(height, width, 3)`) in a grid of `ceil(sqrt(n))`
    columns, row by row, the empty cells black: how a vector env shows all its envs at once."""
    frames = np.asarray(frames)
    count, height, width, channels = frames.shape
    columns = int(np.ceil(np.sqrt(count)))
    rows = -(-count // columns)
    padded = np.concatenate([frames, np.zeros((rows * columns - count, height, width, channels), frames.dtype)])
    grid = padded.reshape(rows, columns, height, width, channels).transpose(0, 2, 1, 3, 4)
    return grid.reshape(rows * height, columns * width, channels)


class HumanWindow:
    """A pygame window showing RGB frames at `fps`, as Gymnasium's `HumanRendering` wrapper shows them."""

    def __init__(self, fps: int):
        require_pygame()
        self.fps = fps
        self._window = None
        self._clock = None

    def show(self, frame: np.ndarray) -> None:
        import pygame

        size = (frame.shape[1], frame.shape[0])
        if self._window is None:
            pygame.init()
            pygame.display.init()
            self._window = pygame.display.set_mode(size)
            self._clock = pygame.time.Clock()
        surface = pygame.surfarray.make_surface(np.transpose(frame, (1, 0, 2)))
        self._window.blit(surface, (0, 0))
        pygame.event.pump()
        self._clock.tick(self.fps)
        pygame.display.flip()

    def close(self) -> None:
        if self._window is not None:
            import pygame

            pygame.display.quit()
            pygame.quit()
            self._window = None


__all__ = ["HumanWindow", "draw", "make_renderer", "render_fps", "require_pygame", "tile"]
