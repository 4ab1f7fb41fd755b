from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE, POSITIVE_OR_INF
from .._types import Array, Input, Key, Scalar, State
from ..env import AbstractEnv, EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics import PendulumDynamics
from ..spaces import Box
from ._registry import register_scene


def _angle_normalize(theta: Scalar) -> Scalar:
    return ((theta + jnp.pi) % (2 * jnp.pi)) - jnp.pi


@register_scene
@final
class Pendulum(AbstractEnv):
    """Swing a pendulum up and hold it upright with a bounded torque (Gymnasium's Pendulum-v1).

    ## Description
    A rod hinged at one end (`PendulumDynamics`). Each step integrates it over `dt` with
    the chosen solver. With `solver="semi_implicit_euler"` (the default) a step is
    Gymnasium's step: the velocity is updated, clipped to `max_speed`, and the angle is
    updated with the new velocity. With any other solver the speed clip is applied after
    the step.

    ## Action Space
    `Box(-max_torque, max_torque, (1,))`: the torque at the pivot (N m), clipped to that range.

    ## Observation Space
    `[cos(theta), sin(theta), theta_dot]`, `theta` from upright.

    ## Rewards
    `-(theta**2 + 0.1 * theta_dot**2 + 0.001 * torque**2)` on the state before the step,
    with `theta` normalised to `[-pi, pi)`.

    ## Starting State
    `theta` uniform in `[-pi, pi]`, `theta_dot` uniform in `[-1, 1]`.

    ## Episode End
    Never terminated, except when the integration fails (`info["solver_ok"]`).
    Truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `PendulumDynamics`) or its parameters flat: `gravity` (10; Gymnasium's
    `g`), `mass` (1), `length` (1). `max_speed` (8, may be `inf`), `max_torque` (2),
    `dt` (0.05), `integrator` or `solver` (a preset name or a diffrax solver) with
    `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    aliases: ClassVar[tuple[tuple[str, str], ...]] = (("g", "gravity"),)

    dynamics: PendulumDynamics = eqx.field(default_factory=PendulumDynamics)
    integrator: Integrator = eqx.field(default="semi_implicit_euler", converter=make_integrator)
    max_speed: Scalar = eqx.field(default=8.0, converter=POSITIVE_OR_INF)
    max_torque: Scalar = eqx.field(default=2.0, converter=POSITIVE)
    dt: Scalar = eqx.field(default=0.05, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(200)

    @property
    def action_space(self) -> Box:
        return Box(-self.max_torque, self.max_torque, (1,))

    @property
    def observation_space(self) -> Box:
        high = jnp.stack([jnp.ones_like(self.max_speed), jnp.ones_like(self.max_speed), self.max_speed])
        return Box(-high, high)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        high = jnp.array([jnp.pi, 1.0], dtype=self.dt.dtype)
        return -high, high

    def physical_input(self, action: Array) -> Input:
        return jnp.clip(jnp.reshape(action, (1,)), -self.max_torque, self.max_torque)

    def project(self, y: State) -> State:
        return y.at[1].set(jnp.clip(y[1], -self.max_speed, self.max_speed))

    def observation(self, state: EnvState, *, key: Key | None) -> Array:
        del key
        theta, theta_dot = state.y
        return jnp.stack([jnp.cos(theta), jnp.sin(theta), theta_dot])

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del next_state, key
        theta, theta_dot = state.y
        torque = self.physical_input(action)[0]
        return -(_angle_normalize(theta) ** 2 + 0.1 * theta_dot**2 + 0.001 * torque**2)

    @property
    def worst_reward(self) -> Scalar:
        # The cost is largest hanging down at full speed and full torque: -16.27 by default.
        return -(jnp.pi**2 + 0.1 * self.max_speed**2 + 0.001 * self.max_torque**2)
