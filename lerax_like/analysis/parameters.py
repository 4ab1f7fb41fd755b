"""Which physical parameters a gradient study differentiates, and what it calls them.

The physical parameters of a scene live in its dynamics, in its friction add-ons (their
coefficients) and in a disk's floor; a study picks them all or some by field name, and names
each entry of the gradient it records.
"""

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import jax
import numpy as np

from ..env import AbstractEnv
from ..gradients import selection_spec


def physical_parameters(env: AbstractEnv) -> tuple[Any, ...]:
    """Where the physical parameters live: the dynamics, a friction add-on's coefficients, a
    disk's floor (its friction and restitution)."""
    floor = getattr(env, "floor", None)
    return (env.dynamics, *getattr(env, "friction", ()), *(() if floor is None else (floor,)))


def parameter_where(env: AbstractEnv, parameters: tuple[str, ...] | None) -> Callable[[AbstractEnv], Any]:
    """The `where` (as `eqx.tree_at` takes it) of the named parameters of `env`'s parts, or of
    all its physical parameters for `None`."""
    if parameters is None:
        return physical_parameters if len(physical_parameters(env)) > 1 else lambda env: env.dynamics
    owner = {name: i for i, part in enumerate(physical_parameters(env)) for name in field_names(part)}
    # `eqx.tree_at` calls `where` on a copy whose leaves, and empty tuples such as a scene's
    # `friction = ()`, are wrapped: index the friction add-ons the env has, never unpack.
    frictions, floor = range(len(getattr(env, "friction", ()))), getattr(env, "floor", None) is not None

    def where(env: AbstractEnv) -> tuple[Any, ...]:
        parts = (env.dynamics, *(env.friction[i] for i in frictions), *((env.floor,) if floor else ()))  # pyright: ignore[reportAttributeAccessIssue]
        return tuple(getattr(parts[owner[name]], name) for name in parameters)

    return where


def field_names(module) -> list[str]:
    """The names of a dynamics' or an add-on's fields."""
    return [field.name for field in dataclasses.fields(module)]


def parameter_names(env: AbstractEnv, where: Callable[[AbstractEnv], Any]) -> list[str]:
    """One name per differentiated element, in the order of the flattened gradient: the env's
    own leaf order (as `eqx.partition` and `ravel_pytree` flatten it), not the order in which
    `where` lists the parameters. Each name is the field's path within its part (the
    dynamics, or a friction add-on): `pole_mass`, `kinetic_friction`.
    """
    parts = {".dynamics", ".floor", *(f".friction[{i}]" for i in range(len(getattr(env, "friction", ()))))}
    chosen = jax.tree.leaves(selection_spec(env, where))
    names = []
    for (path, leaf), selected in zip(jax.tree_util.tree_flatten_with_path(env)[0], chosen, strict=True):
        if not selected:
            continue
        within = next(cut for cut in range(1, len(path)) if jax.tree_util.keystr(path[:cut]) in parts)
        name = jax.tree_util.keystr(path[within:]).lstrip(".")
        size = int(np.size(leaf))
        names.extend([name] if size == 1 else [f"{name}[{i}]" for i in range(size)])
    return names


def check_parameter_names(env: AbstractEnv, names: Sequence[str], scene: str) -> None:
    """Refuses names that are no field of the scene's physical parameters, listing those."""
    fields = {name for part in physical_parameters(env) for name in field_names(part)}
    unknown = [name for name in names if name not in fields]
    if unknown:
        raise ValueError(f"{scene} has no physical parameters {unknown}; it has {sorted(fields)}")
