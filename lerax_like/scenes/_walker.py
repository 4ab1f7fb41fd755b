"""What the walkers' scenes share: walk at a target speed with a bounded torque, until a fall."""

from typing import ClassVar, cast

import equinox as eqx
import jax.numpy as jnp

from .._types import Array, BoolScalar, Key, Scalar
from ..env import EnvState
from ..physics.walker import AbstractWalkerDynamics, HeelStrike
from ._unit_action import AbstractUnitActionEnv


class AbstractWalkerEnv(AbstractUnitActionEnv):
    """A passive walker's scene (`lerax_like.physics.walker`): its heel strikes located as events.

    Reward `-min((v - target_speed)**2, max_cost) - action_cost * a**2` after the step, `v`
    the hip's speed along the slope (`dynamics.hip_speed`); terminated when the walker
    falls, its stance leg at `fall_angle` or more from the slope's normal. Its one action is
    the torque `max_torque * a`, and its one add-on the heel strike.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "max_torque"
    addons: ClassVar[tuple[type, ...]] = (HeelStrike,)

    max_torque: eqx.AbstractVar[Scalar]
    target_speed: eqx.AbstractVar[Scalar]
    max_cost: eqx.AbstractVar[Scalar]
    action_cost: eqx.AbstractVar[Scalar]
    fall_angle: eqx.AbstractVar[Scalar]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        error = (cast(AbstractWalkerDynamics, self.dynamics).hip_speed(next_state.y) - self.target_speed) ** 2
        return -jnp.minimum(error, self.max_cost) - self.action_cost * self.effort(action)

    @property
    def worst_reward(self) -> Scalar:
        return -self.max_cost - self.action_cost

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        return jnp.abs(cast(AbstractWalkerDynamics, self.dynamics).stance_angle(state.y)) >= self.fall_angle
