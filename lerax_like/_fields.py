"""Fields declared once and checked once: how dynamics, add-ons and scenes are constructed.

They are plain Equinox modules: the `__init__` is the one Equinox's dataclass writes from the
fields, which `inspect`, `help()`, IDEs and type checkers read. A physical or task parameter
is a field whose converter is its allowed range,

    pole_mass: Scalar = eqx.field(default=0.1, converter=POSITIVE)

which makes it a floating-point array leaf (so `jax.grad` and `eqx.filter_vmap` reach it);
`AbstractParametrised.__check_init__` then checks every such field against its range, with
the field's name in the message. A static option (one that decides code paths) is
`option(default, choices)`. Checks see concrete values only: under `jax.vmap` a parameter
may be a tracer, which is let through (the integrator reports runtime failures instead).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import equinox as eqx
import jax
import jax.core  # `jax.core.Tracer`: imported by name, so that a type checker sees the module
import jax.numpy as jnp
import numpy as np

from ._types import ArrayLike

Check = Callable[[np.ndarray], bool]


def concrete(value) -> np.ndarray | None:
    """`value` as a NumPy array, None where it is traced or not a number (a check across fields
    then leaves it to the check of each field, which names it)."""
    if isinstance(value, jax.core.Tracer) or isinstance(value, (str, bytes)) or value is None:
        return None
    array = np.asarray(value)
    return array if np.issubdtype(array.dtype, np.number) or array.dtype == np.bool_ else None


def as_parameter(value, name: str) -> jax.Array:
    """A physical parameter as a floating-point array leaf (default float dtype), refused by `name`."""
    converted = _as_float_array(value)
    if not isinstance(converted, jax.Array):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    return converted


def _as_float_array(value) -> Any:
    """`value` as an array of the default float dtype; `value` itself if it is not a real number
    (refused by name in `__check_init__`, which knows the field's name)."""
    if isinstance(value, jax.core.Tracer):
        return value if jnp.issubdtype(value.dtype, jnp.floating) else value.astype(float)
    if isinstance(value, (str, bytes)) or value is None:
        return value
    try:
        return jnp.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return value


@dataclasses.dataclass(frozen=True)
class Range:
    """The allowed range of a parameter, and its converter (`eqx.field(converter=POSITIVE)`).

    Called on a value it returns a floating-point array; `shape`, if given, is the required
    shape, where a name stands for any length >= 1 that every field naming it shares
    (`("n",)` for a chain's per-link masses and lengths, n the number of links).
    """

    description: str
    holds: Check
    shape: tuple[str | int, ...] | None = None

    def __call__(self, value: ArrayLike) -> jax.Array:
        return _as_float_array(value)

    def shaped(self, *shape: str | int) -> ShapedRange:
        """This range for an array of `shape`."""
        return ShapedRange(self.description, self.holds, shape)

    def check(self, value, name: str) -> None:
        array = concrete(value)
        if array is not None and not self.holds(array):
            raise ValueError(f"{name} must be {self.description}, got {array}")


class ShapedRange(Range):
    """A range for an array of a given shape, which takes a sequence of numbers too."""

    def __call__(self, value: ArrayLike | Sequence[float]) -> jax.Array:
        return _as_float_array(value)


POSITIVE = Range("finite and > 0 (allowed range (0, inf))", lambda a: bool(np.all(np.isfinite(a)) and np.all(a > 0)))
NONNEGATIVE = Range("finite and >= 0 (allowed range [0, inf))", lambda a: bool(np.all(np.isfinite(a)) and np.all(a >= 0)))
POSITIVE_OR_INF = Range("> 0 (allowed range (0, inf])", lambda a: bool(np.all(a > 0) and not np.any(np.isnan(a))))
FINITE = Range("finite (allowed range (-inf, inf))", lambda a: bool(np.all(np.isfinite(a))))


def option(default: Any, choices: tuple | None = None, *, static: bool = True) -> Any:
    """A static option (it decides code paths or shapes), one of `choices` if given."""
    return eqx.field(default=default, static=static, metadata={"choices": choices})


_Tree = TypeVar("_Tree")


def in_precision_of(y, x: _Tree) -> _Tree:
    """`x` with its float leaves in `y`'s dtype: an env computes in its own precision, whatever
    the float mode an action or input was made in (float64 for an env built in float32)."""
    return jax.tree.map(lambda v: jnp.asarray(v, y.dtype) if jnp.issubdtype(jnp.result_type(v), jnp.floating) else v, x)


def check_shape(value, shape: tuple[str | int, ...] | None, name: str, sizes: dict[str, tuple[int, str]]) -> None:
    """Refuse `value` unless its shape is `shape`.

    A name in `shape` matches any length >= 1, the same length in every field that uses it:
    `sizes` maps each name already met to its length and the field that set it.
    """
    if shape is None:
        return
    wanted = "(" + ", ".join(map(str, shape)) + ("," if len(shape) == 1 else "") + ")"
    fits = len(value.shape) == len(shape) and all(
        size >= 1 if isinstance(want, str) else size == want for size, want in zip(value.shape, shape)
    )
    if not fits:
        named = [want for want in shape if isinstance(want, str)]
        lengths = f" with {', '.join(named)} >= 1" if named else ""
        raise ValueError(f"{name} must be an array of shape {wanted}{lengths}, got shape {value.shape}")
    for size, want in zip(value.shape, shape):
        if not isinstance(want, str):
            continue
        known, owner = sizes.setdefault(want, (size, name))
        if size != known:
            raise ValueError(
                f"{name} must have shape {wanted} with {want} = {known} (as {owner} has), got shape {value.shape}"
            )


def check_count(value: int, name: str, minimum: int = 1) -> None:
    """Refuse a count (of steps, samples, repeats) that is not an integer >= `minimum`."""
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")


def parameter_range(field: dataclasses.Field) -> Range | None:
    """The range of a parameter field (its converter), None for any other field."""
    converter = field.metadata.get("converter")
    return converter if isinstance(converter, Range) else None


class AbstractParametrised(eqx.Module):
    """Its parameters (fields converted by a `Range`) are checked by name once constructed,
    its options against their choices."""

    def __check_init__(self):
        sizes: dict[str, tuple[int, str]] = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            allowed = parameter_range(field)
            if allowed is not None:
                if not isinstance(value, jax.Array):
                    raise TypeError(f"{field.name} must be a real number, got {value!r}")
                check_shape(value, allowed.shape, field.name, sizes)
                allowed.check(value, field.name)
            choices = field.metadata.get("choices")
            if choices is not None and value not in choices:
                raise ValueError(f"{field.name} must be one of {choices}, got {value!r}")
