"""Scenes by name, for the studies: `make_scene("CartPole", solver="rk4")`.

Everything reads the one registry, `lerax_like.SCENES`, and the metadata each scene class
declares: `stiff` (the SciPy reference then uses Radau instead of DOP853) and whether it
clips or wraps its state (`projects_state()`, which the gradient study refuses).

The SciPy reference integrates the vector field alone: a scene that clips or wraps its
state after each step is measured against the unclipped motion, which is the right
reference only while the projection stays inactive.
"""

from ..env import AbstractEnv
from ..scenes import SCENES


def make_scene(name: str, **kwargs) -> AbstractEnv:
    """The env registered as `name`, built with `kwargs` (its constructor's keywords)."""
    try:
        scene = SCENES[name]
    except KeyError:
        raise ValueError(f"unknown scene {name!r}; known scenes: {', '.join(SCENES)}") from None
    return scene(**kwargs)


def reference_method(name: str) -> str:
    """SciPy's method for the reference of scene `name`: Radau for a stiff scene, else DOP853."""
    return "Radau" if SCENES[name].stiff else "DOP853"


__all__ = ["SCENES", "make_scene", "reference_method"]
