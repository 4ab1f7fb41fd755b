"""Fields declared once and checked once: how dynamics and scenes are constructed.

A physical or task parameter is declared as a field with `parameter(default, check)`; a
static option (one that decides code paths) with `option(default, choices)`. One shared
`__init__` (`AbstractParametrised`) takes every field as a keyword, converts parameters
to floating-point array leaves, runs each field's check with the field's own name in the
message, and refuses unknown keywords naming the closest known one; its signature lists
the fields (`lerax_like._signatures`). Checks see concrete
values only: under `jax.vmap` a parameter may be a tracer, which is let through (the
integrator reports runtime failures instead).
"""

import dataclasses
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax
import jax.core  # `jax.core.Tracer`: imported by name, so that a type checker sees the module
import jax.numpy as jnp
import numpy as np

from ._signatures import Constructor, field_keywords, refuse_unknown


Check = Callable[[np.ndarray], bool]


def concrete(value) -> np.ndarray | None:
    if isinstance(value, jax.core.Tracer):
        return None
    return np.asarray(value)


def as_parameter(value, name: str) -> jax.Array:
    """A physical parameter as a floating-point array leaf (default float dtype)."""
    if isinstance(value, jax.core.Tracer):
        return value if jnp.issubdtype(value.dtype, jnp.floating) else value.astype(float)
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name} must be a real number, got {value!r}")
    try:
        return jnp.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise TypeError(f"{name} must be a real number, got {value!r}") from error


@dataclasses.dataclass(frozen=True)
class Range:
    """An allowed range of a parameter, as the error message states it."""

    description: str
    holds: Check

    def check(self, value, name: str) -> None:
        array = concrete(value)
        if array is not None and not self.holds(array):
            raise ValueError(f"{name} must be {self.description}, got {array}")


POSITIVE = Range("finite and > 0 (allowed range (0, inf))", lambda a: bool(np.all(np.isfinite(a)) and np.all(a > 0)))
NONNEGATIVE = Range("finite and >= 0 (allowed range [0, inf))", lambda a: bool(np.all(np.isfinite(a)) and np.all(a >= 0)))
POSITIVE_OR_INF = Range("> 0 (allowed range (0, inf])", lambda a: bool(np.all(a > 0) and not np.any(np.isnan(a))))
FINITE = Range("finite (allowed range (-inf, inf))", lambda a: bool(np.all(np.isfinite(a))))


def parameter(default: Any = dataclasses.MISSING, check: Range | None = POSITIVE, *, default_from=None, shape=None):
    """A differentiable parameter: a float array leaf, checked against `check` by name.

    `default_from(values)`, if given, computes the default from the fields declared
    before it (a threshold that depends on the task, say). `shape`, if given, is the
    required shape, a name standing for any length >= 1 that every field naming it shares
    (`("n",)` for a chain's per-link masses and lengths, n the number of links).
    """
    metadata = {"parameter": True, "range": check, "default_from": default_from, "shape": shape}
    if default_from is not None:
        default = None
    return eqx.field(default=default, metadata=metadata)


def option(default: Any, choices: tuple | None = None, *, static: bool = True):
    """A static option (it decides code paths or shapes), one of `choices` if given."""
    return eqx.field(default=default, static=static, metadata={"choices": choices})


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


def assign_fields(module: eqx.Module, values: dict[str, Any]) -> None:
    """Set every field of `module` from `values` or its default, converted and checked by name."""
    cls = type(module)
    fields = dataclasses.fields(cls)
    refuse_unknown(cls, values, (field.name for field in fields))
    resolved: dict[str, Any] = {}
    sizes: dict[str, tuple[int, str]] = {}
    for field in fields:
        metadata = field.metadata
        if field.name in values:
            value = values[field.name]
        elif metadata.get("default_from") is not None:
            value = metadata["default_from"](resolved)
        elif field.default is not dataclasses.MISSING:
            value = field.default
        elif field.default_factory is not dataclasses.MISSING:
            value = field.default_factory()
        else:
            raise TypeError(f"{cls.__name__} needs the keyword {field.name}")
        if metadata.get("parameter"):
            value = as_parameter(value, field.name)
            check_shape(value, metadata.get("shape"), field.name, sizes)
            if metadata.get("range") is not None:
                metadata["range"].check(value, field.name)
        choices = metadata.get("choices")
        if choices is not None and value not in choices:
            raise ValueError(f"{field.name} must be one of {choices}, got {value!r}")
        resolved[field.name] = value
        setattr(module, field.name, value)


def _construct(self, **values):
    """Every field by keyword; a parameter is converted to a float array and checked by name."""
    assign_fields(self, values)


class AbstractParametrised(eqx.Module):
    """Constructed by keyword from its fields (see `parameter` and `option`), checked once.

    Its signature (`inspect.signature`, `help()`) lists the fields with their defaults.
    """

    if TYPE_CHECKING:  # a final class declares its own (`lerax_like._constructor_source`)

        def __init__(self, **values: Any) -> None: ...
    else:
        __init__ = Constructor(_construct, field_keywords)


__all__ = [
    "FINITE",
    "NONNEGATIVE",
    "POSITIVE",
    "POSITIVE_OR_INF",
    "AbstractParametrised",
    "Range",
    "as_parameter",
    "assign_fields",
    "check_count",
    "check_shape",
    "option",
    "parameter",
]
