"""Construction-time checks of physical parameters.

Parameters may be tracers when an env is built under `jax.vmap` or `eqx.filter_vmap`;
those cannot be inspected here and are let through (runtime failures are reported by
the integrator instead). Concrete values are checked and refused with a message that
names the parameter and its allowed range.
"""


import jax
import numpy as np

from . import _fields


def as_parameter(value, name: str) -> jax.Array:
    """A physical parameter as a floating-point array leaf (default float dtype)."""
    return _fields.as_parameter(value, name)


def _concrete(value, name: str) -> np.ndarray | None:
    if isinstance(value, jax.core.Tracer):
        return None
    # Refuses a non-number (`"heavy"`) by name before any check computes with it.
    return np.asarray(as_parameter(value, name))


def check_positive(value, name: str) -> None:
    """Refuse a concrete value that is not a finite number > 0."""
    array = _concrete(value, name)
    if array is None:
        return
    if not (np.all(np.isfinite(array)) and np.all(array > 0)):
        raise ValueError(f"{name} must be finite and > 0 (allowed range (0, inf)), got {array}")


def check_nonnegative(value, name: str) -> None:
    """Refuse a concrete value that is not a finite number >= 0."""
    array = _concrete(value, name)
    if array is None:
        return
    if not (np.all(np.isfinite(array)) and np.all(array >= 0)):
        raise ValueError(f"{name} must be finite and >= 0 (allowed range [0, inf)), got {array}")


def check_positive_or_inf(value, name: str) -> None:
    """Refuse a concrete value that is not > 0 (infinity allowed: 'no bound')."""
    array = _concrete(value, name)
    if array is None:
        return
    if not np.all(array > 0) or np.any(np.isnan(array)):
        raise ValueError(f"{name} must be > 0 (allowed range (0, inf]), got {array}")


def check_finite(value, name: str) -> None:
    """Refuse a concrete value that is NaN or infinite."""
    array = _concrete(value, name)
    if array is None:
        return
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite (allowed range (-inf, inf)), got {array}")


def check_count(value: int, name: str, minimum: int = 1) -> None:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


__all__ = [
    "as_parameter",
    "check_count",
    "check_finite",
    "check_nonnegative",
    "check_positive",
    "check_positive_or_inf",
]
