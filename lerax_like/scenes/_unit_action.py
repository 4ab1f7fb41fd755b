"""Continuous actions in the unit box: what the continuous scenes share."""

import abc
from typing import ClassVar

import jax.numpy as jnp

import equinox as eqx

from .._types import Array, Float, Input, Key, Scalar
from ..env import AbstractEnv, EnvState
from ..spaces import Box


class AbstractUnitActionEnv(AbstractEnv):
    """A scene whose action is a vector in `[-1, 1]^n`, clipped to that box before it acts.

    The convention of Gymnasium's continuous control tasks: an agent's output is scaled
    once, by the scene, to a force, a torque or a thrust. The scene declares `action_size`
    (`n`; a class variable, or a property where it depends on the instance) and
    `action_scale`, the parameter that `clipped(action)` is multiplied by to give the
    physical input (`"force_mag"`: a unit action is `force_mag` newtons). A scene whose
    input is no such product (a hover thrust plus a part) writes `physical_input` instead.
    """

    action_scale: ClassVar[str | None] = None
    """The name of the parameter that scales the clipped action to the physical input."""

    @property
    @abc.abstractmethod
    def action_size(self) -> int:
        """The number of entries of an action."""

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (self.action_size,))

    def clipped(self, action: Array) -> Float[Array, " n"]:
        """`action` clipped to `[-1, 1]` entry by entry, as the physics and the rewards read it."""
        return jnp.clip(jnp.reshape(action, (self.action_size,)), -1.0, 1.0)

    def physical_input(self, action: Array) -> Input:
        """`clipped(action)` times the parameter that `action_scale` names."""
        if self.action_scale is None:
            raise NotImplementedError(
                f"{type(self).__name__} must declare `action_scale` (the parameter a unit action is scaled "
                "by) or write `physical_input`"
            )
        return getattr(self, self.action_scale) * self.clipped(action)

    def effort(self, action: Array) -> Float[Array, ""]:
        """The squared norm of `clipped(action)`: the control effort a task's reward charges."""
        return jnp.sum(self.clipped(action) ** 2)


class AbstractReachEnv(AbstractUnitActionEnv):
    """A scene whose task is to bring its first coordinate to `target` and hold it there:
    the reward after a step is `exp(-(x - target)**2) - action_cost * |a|**2` (1 at the
    target, falling off with the distance), `a` the clipped action."""

    target: eqx.AbstractVar[Scalar]
    action_cost: eqx.AbstractVar[Scalar]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        return jnp.exp(-((next_state.y[0] - self.target) ** 2)) - self.action_cost * self.effort(action)

    @property
    def worst_reward(self) -> Scalar:
        return -self.action_cost * jnp.ones((), self.dt.dtype)
