import math
from typing import ClassVar, Literal

import diffrax
import equinox as eqx
import jax.numpy as jnp

from .._checks import as_parameter, check_nonnegative, check_positive, check_positive_or_inf
from .._random import uniform
from .._types import Array, BoolScalar, Input, Key, Scalar, ScalarLike
from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, make_integrator
from ..physics.chain import CartChainDynamics
from ..spaces import Box


class DoubleCartPole(AbstractEnv):
    """Balance, or swing up, two poles in a chain on a cart by pushing the cart.

    ## Description
    A cart on a frictionless rail carries two uniform poles hinged in a chain (the first
    on the cart, the second on the tip of the first). The physics is `CartChainDynamics`
    with two poles (Lagrangian mechanics, `M(q) q'' = Q - C(q, q') - G(q)`); each step
    integrates it over `dt` with the chosen solver. Two tasks:
    `task="balance"` keeps both poles up from a start near upright (as `CartPole`);
    `task="swing_up"` starts with both poles hanging and asks to raise them (the DM Control
    and IDS task).

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range, scaled by `force_mag`: the horizontal
    force on the cart in newtons.

    ## Observation Space
    The state `[x, theta1, theta2, x_dot, theta1_dot, theta2_dot]`: cart position (m),
    pole angles from upright, absolute, positive towards `+x` (rad, not wrapped), and their
    rates. Unbounded.

    ## Rewards
    `balance`: +1 for every step, the terminating step included.
    `swing_up`: `(cos theta1 + cos theta2) / 2 - action_cost * a**2` after the step, with
    `a` the clipped action: 1 upright at rest force, -1 hanging.

    ## Starting State
    `balance`: all six coordinates uniform in `(-0.05, 0.05)`.
    `swing_up`: both angles `pi` plus uniform `(-0.05, 0.05)`, the other coordinates
    uniform in `(-0.05, 0.05)`.

    ## Episode End
    Terminated when `|x| > x_threshold`, when the integration fails (`info["solver_ok"]`),
    and for `balance` when `|theta1|` or `|theta2|` exceeds `theta_threshold_radians`.
    Truncated after `max_episode_steps` (500) steps.

    ## Arguments
    `task` ("balance" or "swing_up"), `cart_mass`, `pole_masses` (2,), `pole_lengths` (2,)
    (full lengths), `gravity`, `force_mag`, `theta_threshold_radians` (12 degrees),
    `x_threshold` (2.4 m for balance, `inf` for swing-up unless given), `action_cost`,
    `dt`, `solver` (a preset name, a diffrax solver or an `Integrator`; default "rk4"),
    `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: CartChainDynamics
    integrator: Integrator
    dt: Scalar
    force_mag: Scalar
    theta_threshold_radians: Scalar
    x_threshold: Scalar
    action_cost: Scalar
    max_episode_steps: int | None = eqx.field(static=True)
    task: Literal["balance", "swing_up"] = eqx.field(static=True)

    def __init__(
        self,
        *,
        task: Literal["balance", "swing_up"] = "balance",
        cart_mass: ScalarLike = 1.0,
        pole_masses=(0.1, 0.1),
        pole_lengths=(1.0, 1.0),
        gravity: ScalarLike = 9.81,
        force_mag: ScalarLike = 20.0,
        theta_threshold_radians: ScalarLike = 12 * 2 * math.pi / 360,
        x_threshold: ScalarLike | None = None,
        action_cost: ScalarLike = 1e-3,
        dt: ScalarLike = 0.02,
        solver: "str | diffrax.AbstractSolver | Integrator" = "rk4",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 500,
    ):
        if task not in ("balance", "swing_up"):
            raise ValueError(f"task must be 'balance' or 'swing_up', got {task!r}")
        if x_threshold is None:
            x_threshold = 2.4 if task == "balance" else math.inf
        dynamics = CartChainDynamics(
            cart_mass=cart_mass, pole_masses=pole_masses, pole_lengths=pole_lengths, gravity=gravity
        )
        if dynamics.n_links != 2:
            raise ValueError(f"pole_masses and pole_lengths must have shape (2,), got {dynamics.pole_masses.shape}")
        check_positive(force_mag, "force_mag")
        check_positive_or_inf(theta_threshold_radians, "theta_threshold_radians")
        check_positive_or_inf(x_threshold, "x_threshold")
        check_nonnegative(action_cost, "action_cost")
        check_positive(dt, "dt")
        self.dynamics = dynamics
        self.integrator = make_integrator(solver, stepsize_controller)
        self.dt = as_parameter(dt, "dt")
        self.force_mag = as_parameter(force_mag, "force_mag")
        self.theta_threshold_radians = as_parameter(theta_threshold_radians, "theta_threshold_radians")
        self.x_threshold = as_parameter(x_threshold, "x_threshold")
        self.action_cost = as_parameter(action_cost, "action_cost")
        self.max_episode_steps = max_episode_steps
        self.task = task

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (1,))

    @property
    def observation_space(self) -> Box:
        return Box(-jnp.inf, jnp.inf, (6,))

    def initial(self, *, key: Key) -> EnvState:
        y = uniform(key, (6,), self.dt.dtype, -0.05, 0.05)
        if self.task == "swing_up":
            y = y.at[1:3].add(math.pi)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def physical_input(self, action: Array) -> Input:
        return self.force_mag * jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        return state.y

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, key
        if self.task == "balance":
            return jnp.ones((), dtype=self.dt.dtype)
        clipped = jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)[0]
        _, theta1, theta2 = next_state.y[:3]
        return (jnp.cos(theta1) + jnp.cos(theta2)) / 2 - self.action_cost * clipped**2

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del key
        x, theta1, theta2 = state.y[:3]
        out = jnp.abs(x) > self.x_threshold
        if self.task == "balance":
            out = (
                out
                | (jnp.abs(theta1) > self.theta_threshold_radians)
                | (jnp.abs(theta2) > self.theta_threshold_radians)
            )
        return out
