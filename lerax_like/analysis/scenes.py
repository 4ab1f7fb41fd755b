"""Scenes by name, for the studies: `make("CartPole", solver="rk4")` (`lerax_like.make`).

Everything reads the one registry, `lerax_like.SCENES`, and the metadata each scene class
declares: `stiff` (the SciPy reference then uses Radau instead of DOP853) and whether it
clips or wraps its state (`projects_state()`, which the gradient study refuses).

The SciPy reference integrates the vector field alone: a scene that clips or wraps its
state after each step is measured against the unclipped motion, which is the right
reference only while the projection stays inactive.
"""

from ..scenes import SCENES, make


def reference_method(name: str) -> str:
    """SciPy's method for the reference of scene `name`: Radau for a stiff scene, else DOP853."""
    return "Radau" if SCENES[name].stiff else "DOP853"


__all__ = ["SCENES", "make", "reference_method"]
