import math
from typing import ClassVar

import diffrax
import equinox as eqx
import jax.numpy as jnp

from .._checks import as_parameter, check_nonnegative, check_positive
from .._random import uniform
from .._types import Array, BoolScalar, Input, Key, Scalar, ScalarLike
from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, make_integrator
from ..physics.chain import NLinkPendulumDynamics
from ..spaces import Box


class NLinkPendulum(AbstractEnv):
    """A chain of n uniform rods hanging from a fixed pivot, with a motor at every joint.

    ## Description
    The compound pendulum of the IDS paper (interactive differentiable simulation): n
    uniform thin rods in a chain from a fixed pivot. The physics is `NLinkPendulumDynamics`
    (Lagrangian mechanics, `M(q) q'' = Q - C(q, q') - G(q)`); each step integrates it over
    `dt` with the chosen solver. With `max_torque=0` (the default) the chain is passive: a
    testbed for parameter identification and for energy conservation.

    ## Action Space
    `Box(-1, 1, (n,))`, clipped to that range, scaled by `max_torque`: `u_i` is the torque
    (N m) that rod `i - 1` (the ground for the first rod) exerts on rod `i`.

    ## Observation Space
    The state `[theta_1, ..., theta_n, theta_1_dot, ..., theta_n_dot]`: absolute angles from
    upright, positive towards `+x` (rad, not wrapped), and their rates. Unbounded.

    ## Rewards
    `mean_i cos(theta_i) - action_cost * |a|**2` after the step, with `a` the clipped
    action: 1 with the chain upright, -1 hanging.

    ## Starting State
    Angles uniform in `(-pi, pi)`, angular velocities uniform in `(-0.05, 0.05)`.

    ## Episode End
    Terminated only when the integration fails (`info["solver_ok"]`). Truncated after
    `max_episode_steps` (500) steps.

    ## Arguments
    `masses` (n,), `lengths` (n,) (full lengths), `gravity`, `max_torque` (>= 0),
    `action_cost`, `dt`, `solver` (a preset name, a diffrax solver or an `Integrator`;
    default "rk4"), `stepsize_controller`, `max_episode_steps`. The number of links n is
    the length of `masses`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: NLinkPendulumDynamics
    integrator: Integrator
    dt: Scalar
    max_torque: Scalar
    action_cost: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        masses=(1.0, 1.0, 1.0),
        lengths=(1.0, 1.0, 1.0),
        gravity: ScalarLike = 9.81,
        max_torque: ScalarLike = 0.0,
        action_cost: ScalarLike = 1e-3,
        dt: ScalarLike = 0.02,
        solver: "str | diffrax.AbstractSolver | Integrator" = "rk4",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 500,
    ):
        check_nonnegative(max_torque, "max_torque")
        check_nonnegative(action_cost, "action_cost")
        check_positive(dt, "dt")
        self.dynamics = NLinkPendulumDynamics(masses=masses, lengths=lengths, gravity=gravity)
        self.integrator = make_integrator(solver, stepsize_controller)
        self.dt = as_parameter(dt, "dt")
        self.max_torque = as_parameter(max_torque, "max_torque")
        self.action_cost = as_parameter(action_cost, "action_cost")
        self.max_episode_steps = max_episode_steps

    @property
    def n_links(self) -> int:
        return self.dynamics.n_links

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (self.n_links,))

    @property
    def observation_space(self) -> Box:
        return Box(-jnp.inf, jnp.inf, (2 * self.n_links,))

    def initial(self, *, key: Key) -> EnvState:
        # Angles uniform in [-pi, pi), rates in [-0.05, 0.05).
        high = jnp.repeat(jnp.array([math.pi, 0.05], dtype=self.dt.dtype), self.n_links)
        y = uniform(key, (2 * self.n_links,), self.dt.dtype, -high, high)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def physical_input(self, action: Array) -> Input:
        return self.max_torque * jnp.clip(jnp.reshape(action, (self.n_links,)), -1.0, 1.0)

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        return state.y

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, key
        clipped = jnp.clip(jnp.reshape(action, (self.n_links,)), -1.0, 1.0)
        return jnp.mean(jnp.cos(next_state.y[: self.n_links])) - self.action_cost * jnp.sum(clipped**2)

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del state, key
        return jnp.asarray(False)
