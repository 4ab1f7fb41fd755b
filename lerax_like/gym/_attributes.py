"""Gymnasium's attributes of an id's env (`masspole`, `tau`, `g`, ...) on the objects that show its scene."""

import dataclasses
import functools
import operator
from typing import Any

import equinox as eqx
import numpy as np

from .._fields import as_parameter
from ._compiled import float64


def _replace(scene, path: str, value, name: str):
    """`scene` with the leaf at `path` replaced by `value`, refused by Gymnasium's `name`
    if the parameter's own constructor refuses it (range, type, checks across fields)."""
    *owner_path, field_name = path.split(".")
    owner = functools.reduce(getattr, owner_path, scene)
    old = getattr(owner, field_name)
    new = as_parameter(value, name).astype(old.dtype)
    if new.shape != old.shape:
        raise ValueError(f"{name} must have shape {old.shape}, got {new.shape}")
    # `eqx.tree_at` skips the constructor's checks: run them on a copy built by keyword.
    values = {field.name: getattr(owner, field.name) for field in dataclasses.fields(owner) if field.init}
    try:
        type(owner)(**{**values, field_name: new})
    except (TypeError, ValueError) as error:
        raise type(error)(f"{name} (the scene's {path}): {error}") from error
    return eqx.tree_at(operator.attrgetter(path), scene, new)


class GymnasiumAttributes:
    """Gymnasium's attributes of the id's env on an object holding the id's `GymSpec` as
    `_gym_spec` and a `scene`: `gravity`, `masscart`, `length`, `tau`, `x_threshold` on
    CartPole; `g`, `m`, `l`, `max_speed` on Pendulum; ... (`GymSpec.attribute_paths`).

    Reading one gives the scene's parameter as a float (in float64). Writing one replaces
    that leaf of the scene (`eqx.tree_at`; each leaf, where Gymnasium's one attribute is
    several parameters), checked as the scene's constructor checks it, and so changes the
    physics from the next step on, as in Gymnasium; the parameters are an argument of the
    compiled step, so nothing recompiles.
    """

    scene: Any

    def __getattr__(self, name: str) -> Any:
        # Only for names the object and its class lack. Through `__dict__`: an object being
        # unpickled or built has no `_gym_spec` yet.
        spec = self.__dict__.get("_gym_spec")
        if spec is None or name not in spec.attribute_paths:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        with float64():
            return float(np.asarray(operator.attrgetter(spec.attribute_paths[name][0])(self.scene)))

    def __setattr__(self, name: str, value: Any) -> None:
        # Every attribute written comes here, a step's own among them: the common case first,
        # as directly as it can be told (object's own, as no class between defines one).
        spec = self.__dict__.get("_gym_spec")
        if spec is None or name not in spec.attribute_paths:
            object.__setattr__(self, name, value)
            return
        with float64():
            scene = self.scene
            for path in spec.attribute_paths[name]:
                scene = _replace(scene, path, value, name)
            self.scene = scene
