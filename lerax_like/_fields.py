"""Fields declared once and checked once: how dynamics and scenes are constructed.

A physical or task parameter is declared as a field with `parameter(default, check)`; a
static option (one that decides code paths) with `option(default, choices)`. One shared
`__init__` (`AbstractParametrised`) takes every field as a keyword, converts parameters
to floating-point array leaves, runs each field's check with the field's own name in the
message, and refuses unknown keywords with the list of known ones. Checks see concrete
values only: under `jax.vmap` a parameter may be a tracer, which is let through (the
integrator reports runtime failures instead).
"""

import dataclasses
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


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
    required number of dimensions (1 for per-link arrays).
    """
    metadata = {"parameter": True, "range": check, "default_from": default_from, "ndim": shape}
    if default_from is not None:
        default = None
    return eqx.field(default=default, metadata=metadata)


def option(default: Any, choices: tuple | None = None, *, static: bool = True):
    """A static option (it decides code paths or shapes), one of `choices` if given."""
    return eqx.field(default=default, static=static, metadata={"choices": choices})


def assign_fields(module: eqx.Module, values: dict[str, Any]) -> None:
    """Set every field of `module` from `values` or its default, converted and checked by name."""
    cls = type(module)
    fields = dataclasses.fields(cls)
    known = {field.name for field in fields}
    unknown = sorted(set(values) - known)
    if unknown:
        raise TypeError(
            f"{cls.__name__} got unknown keyword(s) {', '.join(unknown)}; "
            f"it takes {', '.join(sorted(known))}"
        )
    resolved: dict[str, Any] = {}
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
            ndim = metadata.get("ndim")
            if ndim is not None and (value.ndim != ndim or value.shape[0] < 1):
                raise ValueError(f"{field.name} must be a one-dimensional array of at least one entry, got shape {value.shape}")
            if metadata.get("range") is not None:
                metadata["range"].check(value, field.name)
        choices = metadata.get("choices")
        if choices is not None and value not in choices:
            raise ValueError(f"{field.name} must be one of {choices}, got {value!r}")
        resolved[field.name] = value
        setattr(module, field.name, value)


class AbstractParametrised(eqx.Module):
    """Constructed by keyword from its fields (see `parameter` and `option`), checked once."""

    def __init__(self, **values):
        assign_fields(self, values)


__all__ = [
    "FINITE",
    "NONNEGATIVE",
    "POSITIVE",
    "POSITIVE_OR_INF",
    "AbstractParametrised",
    "Range",
    "as_parameter",
    "assign_fields",
    "option",
    "parameter",
]
