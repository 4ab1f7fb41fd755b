"""`Params`: the data of a gymnax env, as gymnax's `EnvParams` is."""

import dataclasses
from typing import final

import equinox as eqx

from .._types import IntScalar
from ..env import AbstractEnv


@final
class Params(eqx.Module):
    """What a gymnax env of a scene computes with, as data (a pytree of arrays).

    - `scene`: the scene's array leaves, in the scene's own structure (its other fields
      None): `params.scene.dynamics.pole_mass`, `params.scene.dt`. Batch a leaf and
      `jax.vmap` over `params` to train over physical parameters, as over gymnax's params.
    - `max_steps_in_episode`: the episode limit (gymnax's name), an integer array.

    `params.replace(max_steps_in_episode=200)`, as gymnax's flax dataclasses;
    `eqx.tree_at(lambda p: p.scene.dynamics.pole_mass, params, 0.2)` for a scene leaf.
    """

    scene: AbstractEnv
    max_steps_in_episode: IntScalar

    def replace(self, **changes) -> "Params":
        return dataclasses.replace(self, **changes)
