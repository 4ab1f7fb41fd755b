"""Rendering: Gymnasium's own classic-control renderers, or lerax_like's pictures.

A scene standing for a Gymnasium env is drawn by an instance of Gymnasium's env class,
used only to draw: before each frame its state and drawing parameters (track width, pole
length, link lengths, hill bounds) are copied from our scene (`GymSpec.render_sync`), so
that its frames are Gymnasium's, pixel for pixel; pygame (the `render` extra) draws them,
as for Gymnasium. Every other scene is drawn by its renderer of `RENDERERS` with NumPy
alone: its `rgb_array` needs no pygame, and `human` shows the frames in a pygame window.
pygame is imported only when it is needed.
"""

import dataclasses
import importlib
from typing import Any

import numpy as np
from gymnasium.error import DependencyNotInstalled

from ._compiled import float64
from ._renderers import render_frame
from ._specs import GymSpec


def require_pygame() -> None:
    try:
        import pygame  # noqa: F401
    except ImportError as error:
        raise DependencyNotInstalled(
            'pygame is not installed, run `pip install "lerax_like[render]"` to render'
        ) from error


def _renderer_class(spec: GymSpec) -> type:
    if spec.renderer is None:  # callers ask only for a spec drawn by Gymnasium's env
        raise ValueError(f"{spec!r} has no Gymnasium renderer")
    module, name = spec.renderer.split(":")
    return getattr(importlib.import_module(module), name)


def render_fps(spec: GymSpec) -> int:
    """Gymnasium's frame rate for its envs; real time (one frame per default `dt`) for the others."""
    if spec.renderer is not None:
        return _renderer_class(spec).metadata["render_fps"]
    defaults: dict[str, Any] = {field.name: field.default for field in dataclasses.fields(spec.scene)}
    dt = defaults["dt"]
    return max(1, round(1 / float(dt)))


class GymnasiumRenderer:
    """Gymnasium's env class of the id, used only to draw (`render_mode` its own)."""

    def __init__(self, spec: GymSpec, render_mode: str):
        require_pygame()
        self._spec = spec
        self._env = _renderer_class(spec)(render_mode=render_mode)

    def draw(self, scene: Any, state: np.ndarray, action: np.ndarray | np.int64 | None):
        with float64():
            self._spec.render_sync(self._env, scene, np.array(state, dtype=np.float64), action)
        return self._env.render()

    def close(self) -> None:
        self._env.close()


class SceneRenderer:
    """lerax_like's picture of a scene (`render_frame`): returned in `rgb_array`, shown in
    a window in `human` (which returns None, as Gymnasium's human renderers do)."""

    def __init__(self, render_mode: str, fps: int):
        self._window = HumanWindow(fps) if render_mode == "human" else None

    def draw(self, scene: Any, state: np.ndarray, action: np.ndarray | np.int64 | None):
        frame = render_frame(scene, state, action)
        if self._window is None:
            return frame
        self._window.show(frame)
        return None

    def close(self) -> None:
        if self._window is not None:
            self._window.close()


def make_renderer(spec: GymSpec, render_mode: str) -> GymnasiumRenderer | SceneRenderer:
    if spec.renderer is not None:
        return GymnasiumRenderer(spec, render_mode)
    return SceneRenderer(render_mode, render_fps(spec))


def tile(frames: list[np.ndarray]) -> np.ndarray:
    """The frames (all of one shape, `(height, width, 3)`) in a grid of `ceil(sqrt(n))`
    columns, row by row, the empty cells black: how a vector env shows all its envs at once."""
    stack = np.asarray(frames)
    count, height, width, channels = stack.shape
    columns = int(np.ceil(np.sqrt(count)))
    rows = -(-count // columns)
    padded = np.concatenate([stack, np.zeros((rows * columns - count, height, width, channels), stack.dtype)])
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
        if self._window is None or self._clock is None:  # both made together, here
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
