"""The gymnax `Environment` over a scene (this module imports gymnax)."""

import math
from typing import final

import equinox as eqx
import jax
import jax.numpy as jnp
from gymnax.environments import environment as gymnax_environment, spaces as gymnax_spaces

from ..env import AbstractEnv, EnvState
from ..spaces import AbstractSpace, Box, Discrete
from ._params import Params


# gymnax 1.x asks `is_truncated` for the time limit and returns terminated and truncated
# apart (six values); 0.0.x has no `is_truncated` and wants `step_env`'s `done` to
# include the time limit (five values).
_SEPARATE_TRUNCATION = hasattr(gymnax_environment.Environment, "is_truncated")

# `max_steps_in_episode` of a scene built without a limit: 2**31 - 1 steps is none in practice.
_NO_LIMIT = jnp.iinfo(jnp.int32).max


def _with_limit(scene: AbstractEnv, limit) -> AbstractEnv:
    return eqx.tree_at(lambda s: s.max_episode_steps, scene, limit, is_leaf=lambda x: x is None)


@final
class Environment(gymnax_environment.Environment):
    """gymnax's `Environment` over the scene `scene`, named `name` (see `lerax_like.gymnax`).

    `step_env` is the scene's `advance` (its failure guards included) with the time
    limit of `params`; `reset_env` is the scene's `reset`; gymnax's own `step` and `reset`
    add the autoreset. Observations, rewards and terminations are the scene's, unchanged.
    Nothing is cut from the gradient (gymnax's own envs stop it): the scenes are
    differentiable, and a trainer that needs no gradient pays nothing for one.
    """

    _supports_transition_gradients = True
    _transition_gradients_enabled = True

    def __init__(self, scene: AbstractEnv, name: str | None = None):
        limit = scene.max_episode_steps
        arrays, self._static = eqx.partition(_with_limit(scene, None), eqx.is_array)
        self._default_params = Params(
            scene=arrays, max_steps_in_episode=jnp.asarray(_NO_LIMIT if limit is None else limit, dtype=int)
        )
        self._name = type(scene).__name__ if name is None else name

    def scene(self, params: Params) -> AbstractEnv:
        """The functional env (`lerax_like.AbstractEnv`) that `params` describe."""
        return _with_limit(eqx.combine(params.scene, self._static), params.max_steps_in_episode)

    @property
    def default_params(self) -> Params:
        return self._default_params

    def step_env(self, key, state: EnvState, action, params: Params):
        scene = self.scene(params)
        state, observation, reward, terminated, info = scene.advance(state, action, key=key)
        truncated = scene.truncate(state)
        info = {**info, "terminated": terminated, "truncated": truncated}
        done = terminated if _SEPARATE_TRUNCATION else terminated | truncated
        return observation, state, reward, done, info

    def reset_env(self, key, params: Params):
        state, observation, _ = self.scene(params).reset(key=key)
        return observation, state

    def is_truncated(self, state: EnvState, params: Params):
        return self.scene(params).truncate(state)

    @property
    def name(self) -> str:
        return self._name

    @property
    def num_actions(self) -> int:
        space = self.scene(self.default_params).action_space
        return space.n if isinstance(space, Discrete) else math.prod(space.shape)

    def action_space(self, params: Params | None = None):
        return _to_gymnax(self.scene(self.default_params if params is None else params).action_space)

    def observation_space(self, params: Params | None = None):
        return _to_gymnax(self.scene(self.default_params if params is None else params).observation_space)


def _to_gymnax(space: AbstractSpace):
    if isinstance(space, Discrete):
        discrete = gymnax_spaces.Discrete(space.n)
        # gymnax 0.0.9 samples with `.astype(jnp.int_)`, int64 whatever the mode: without
        # x64 (rejax trains in float32) every `sample` warned that int64 is truncated to
        # int32. The integer type of the current mode is what `astype` gives there anyway.
        discrete.dtype = jax.dtypes.canonicalize_dtype(jnp.int_)
        return discrete
    if isinstance(space, Box):
        # NumPy bounds where concrete (`lerax_like.spaces`), which gymnax takes although it
        # annotates `low` and `high` as a JAX array or a float.
        return gymnax_spaces.Box(
            space.low, space.high, space.shape, space.low.dtype  # pyright: ignore[reportArgumentType]
        )
    raise TypeError(f"no gymnax counterpart for the space {space!r}")
