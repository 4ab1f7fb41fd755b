import math
from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE
from .._types import Array, BoolScalar, Input, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.planar_quadrotor import PlanarQuadrotorDynamics
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv


@register_scene
@final
class PlanarQuadrotor(AbstractUnitActionEnv):
    """Hold a planar quadrotor hovering at the origin with its two rotors' thrusts.

    ## Description
    A quadrotor in the vertical plane (`PlanarQuadrotorDynamics`): two rotors at the ends
    of its arm thrust along the body's up axis. Each step integrates the dynamics over
    `dt` with the chosen solver (`"rk4"` by default). The task is to hover at the origin,
    level.

    ## Action Space
    `Box(-1, 1, (2,))`, clipped to that range, around hover: rotor `i` thrusts
    `(1 + a_i) * mass * gravity / 2` newtons, so `a = 0` hovers and each rotor ranges from
    off to twice its hover thrust.

    ## Observation Space
    The state `[x, z, theta, x_dot, z_dot, theta_dot]`, unbounded.

    ## Rewards
    `1 - (x^2 + z^2) / (4 L^2) - theta^2 / (4 theta_limit^2) - mean(a^2) / 4` after the
    step, with `L = position_limit` and positions and angle clipped to their limits:
    1 hovering level at the origin with no effort, never below 0.

    ## Starting State
    Position uniform in `(-0.5, 0.5)` m, attitude in `(-0.1, 0.1)` rad, rates in
    `(-0.1, 0.1)`.

    ## Episode End
    Terminated when `|x|` or `|z|` exceeds `position_limit` (2 m) or `|theta|` exceeds
    `theta_limit` (pi / 2), or when the integration fails (`info["solver_ok"]`).
    Truncated after `max_episode_steps` (500) steps.

    ## Arguments
    `dynamics` (a `PlanarQuadrotorDynamics`) or its parameters flat: `mass`, `arm_length`,
    `moment_of_inertia`, `gravity`. `position_limit`, `theta_limit`, `dt`, `integrator` or
    `solver` with `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 2

    dynamics: PlanarQuadrotorDynamics = eqx.field(default_factory=PlanarQuadrotorDynamics)
    integrator: Integrator = eqx.field(default="rk4", converter=make_integrator)
    position_limit: Scalar = eqx.field(default=2.0, converter=POSITIVE)
    theta_limit: Scalar = eqx.field(default=math.pi / 2, converter=POSITIVE)
    action_cost: Scalar = eqx.field(default=0.25, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(500)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        high = jnp.array([0.5, 0.5, 0.1, 0.1, 0.1, 0.1], self.dt.dtype)
        return -high, high

    def physical_input(self, action: Array) -> Input:
        hover = self.dynamics.mass * self.dynamics.gravity / 2
        return hover * (1.0 + self.clipped(action))

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        limit = self.position_limit
        position = jnp.clip(next_state.y[:2], -limit, limit)
        theta = jnp.clip(next_state.y[2], -self.theta_limit, self.theta_limit)
        effort = jnp.mean(self.clipped(action) ** 2)
        return (
            1.0
            - jnp.sum(position**2) / (4 * limit**2)
            - theta**2 / (4 * self.theta_limit**2)
            - self.action_cost * effort
        )

    @property
    def worst_reward(self) -> Scalar:
        return 0.5 - 0.25 - self.action_cost

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        x, z, theta = state.y[:3]
        return (jnp.maximum(jnp.abs(x), jnp.abs(z)) > self.position_limit) | (jnp.abs(theta) > self.theta_limit)
