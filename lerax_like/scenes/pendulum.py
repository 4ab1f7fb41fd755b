from typing import ClassVar

import diffrax
import equinox as eqx
import jax.numpy as jnp

from .._checks import as_parameter, check_positive, check_positive_or_inf
from .._random import uniform
from .._types import Array, BoolScalar, Input, Key, Scalar, ScalarLike, State
from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, make_integrator
from ..physics import PendulumDynamics
from ..spaces import Box


SolverLike = "str | diffrax.AbstractSolver | Integrator"


def _angle_normalize(theta: Scalar) -> Scalar:
    return ((theta + jnp.pi) % (2 * jnp.pi)) - jnp.pi


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
    `gravity` (10), `mass` (1), `length` (1), `max_speed` (8, may be `inf`),
    `max_torque` (2), `dt` (0.05), `solver` (a preset name, a diffrax solver or an
    `Integrator`), `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: PendulumDynamics
    integrator: Integrator
    dt: Scalar
    max_speed: Scalar
    max_torque: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        gravity: ScalarLike = 10.0,
        mass: ScalarLike = 1.0,
        length: ScalarLike = 1.0,
        max_speed: ScalarLike = 8.0,
        max_torque: ScalarLike = 2.0,
        dt: ScalarLike = 0.05,
        solver: SolverLike = "semi_implicit_euler",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 200,
    ):
        check_positive_or_inf(max_speed, "max_speed")
        check_positive(max_torque, "max_torque")
        check_positive(dt, "dt")
        self.dynamics = PendulumDynamics(gravity=gravity, mass=mass, length=length)
        self.integrator = make_integrator(solver, stepsize_controller)
        self.dt = as_parameter(dt, "dt")
        self.max_speed = as_parameter(max_speed, "max_speed")
        self.max_torque = as_parameter(max_torque, "max_torque")
        self.max_episode_steps = max_episode_steps

    @property
    def action_space(self) -> Box:
        return Box(-self.max_torque, self.max_torque, (1,))

    @property
    def observation_space(self) -> Box:
        high = jnp.stack([jnp.ones_like(self.max_speed), jnp.ones_like(self.max_speed), self.max_speed])
        return Box(-high, high)

    def initial(self, *, key: Key) -> EnvState:
        high = jnp.array([jnp.pi, 1.0], dtype=self.dt.dtype)
        y = uniform(key, (2,), self.dt.dtype, -high, high)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def physical_input(self, action: Array) -> Input:
        return jnp.clip(jnp.reshape(action, (1,)), -self.max_torque, self.max_torque)

    def project(self, y: State) -> State:
        return y.at[1].set(jnp.clip(y[1], -self.max_speed, self.max_speed))

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        theta, theta_dot = state.y
        return jnp.stack([jnp.cos(theta), jnp.sin(theta), theta_dot])

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del next_state, key
        theta, theta_dot = state.y
        torque = self.physical_input(action)[0]
        return -(_angle_normalize(theta) ** 2 + 0.1 * theta_dot**2 + 0.001 * torque**2)

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del state, key
        return jnp.asarray(False)
