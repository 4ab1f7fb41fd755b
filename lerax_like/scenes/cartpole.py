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
from ..physics import CartPoleDynamics, EndStops, ForcedDynamics, JointDamping
from ..spaces import Box, Discrete


SolverLike = "str | diffrax.AbstractSolver | Integrator"


def _cartpole_parts(
    gravity, cart_mass, pole_mass, half_length, force_mag, theta_threshold_radians, x_threshold, dt,
    solver, stepsize_controller, joint_damping=None, end_stop_stiffness=None, end_stop_damping=None,
    track_limit=None,
) -> tuple["CartPoleDynamics | ForcedDynamics", Integrator, Scalar, Scalar, Scalar, Scalar]:
    check_positive(force_mag, "force_mag")
    check_positive_or_inf(theta_threshold_radians, "theta_threshold_radians")
    check_positive_or_inf(x_threshold, "x_threshold")
    check_positive(dt, "dt")
    # Temporary wiring until the scenes take their add-ons by a general mechanism: an
    # add-on is built only when one of its keywords is given.
    dynamics = CartPoleDynamics(gravity=gravity, cart_mass=cart_mass, pole_mass=pole_mass, half_length=half_length)
    forces = []
    if joint_damping is not None:
        forces.append(JointDamping(joint_damping))
    stops = dict(end_stop_stiffness=end_stop_stiffness, end_stop_damping=end_stop_damping, track_limit=track_limit)
    if any(value is not None for value in stops.values()):
        forces.append(EndStops(**{name: value for name, value in stops.items() if value is not None}))
    return (
        ForcedDynamics(dynamics, forces) if forces else dynamics,
        make_integrator(solver, stepsize_controller),
        as_parameter(dt, "dt"),
        as_parameter(force_mag, "force_mag"),
        as_parameter(theta_threshold_radians, "theta_threshold_radians"),
        as_parameter(x_threshold, "x_threshold"),
    )


class AbstractCartPole(AbstractEnv):
    """What the discrete and continuous cart-poles share: physics, start, observation, end."""

    dynamics: eqx.AbstractVar[CartPoleDynamics | ForcedDynamics]
    force_mag: eqx.AbstractVar[Scalar]
    theta_threshold_radians: eqx.AbstractVar[Scalar]
    x_threshold: eqx.AbstractVar[Scalar]

    @property
    def observation_space(self) -> Box:
        high = jnp.stack(
            [2 * self.x_threshold, jnp.inf, 2 * self.theta_threshold_radians, jnp.inf]
        )
        return Box(-high, high)

    def initial(self, *, key: Key) -> EnvState:
        y = uniform(key, (4,), self.dt.dtype, -0.05, 0.05)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        return state.y

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del key
        x, _, theta, _ = state.y
        return (
            (x < -self.x_threshold)
            | (x > self.x_threshold)
            | (theta < -self.theta_threshold_radians)
            | (theta > self.theta_threshold_radians)
        )


class CartPole(AbstractCartPole):
    """Balance a pole on a cart by pushing the cart left or right (Gymnasium's CartPole-v1).

    ## Description
    A pole is hinged to a cart on a frictionless track (Barto, Sutton and Anderson, 1983).
    The physics is `CartPoleDynamics`; each step integrates it over `dt` with the chosen
    solver. With `solver="euler"` (the default) a step is Gymnasium's step.

    ## Action Space
    `Discrete(2)`: 0 pushes the cart left, 1 pushes it right, with `force_mag` newtons.

    ## Observation Space
    `[x, x_dot, theta, theta_dot]`: cart position (m) and velocity (m/s), pole angle from
    upright (rad) and angular velocity (rad/s).

    ## Rewards
    +1 for every step, the terminating step included.

    ## Starting State
    All four coordinates uniform in `(-0.05, 0.05)`.

    ## Episode End
    Terminated when `|theta| > theta_threshold_radians` (12 degrees) or
    `|x| > x_threshold` (2.4 m), or when the integration fails (`info["solver_ok"]`).
    Truncated after `max_episode_steps` (500) steps.

    ## Arguments
    `gravity`, `cart_mass`, `pole_mass`, `half_length`, `force_mag`,
    `theta_threshold_radians`, `x_threshold`, `dt`, `solver` (a preset name, a diffrax
    solver or an `Integrator`), `stepsize_controller`, `max_episode_steps`.
    Stiff options of real rigs, off (0) by default so that Gymnasium's step is kept:
    `joint_damping` (hinge friction, N m s/rad; 300 is very stiff), `end_stop_stiffness`
    and `end_stop_damping` (one-sided spring-dampers at `x = +-track_limit`, stiffness up
    to 1e6 N/m; a contact), `track_limit` (m, the stops' position, default 2.4; set
    `x_threshold=inf` to let the cart reach them). They are the add-ons `JointDamping` and
    `EndStops` of `lerax_like.physics.forces`, built only when given; stiff settings
    need an adaptive solver (`"tsit5"`) or an implicit one (`"kvaerno5"`).
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: CartPoleDynamics | ForcedDynamics
    integrator: Integrator
    dt: Scalar
    force_mag: Scalar
    theta_threshold_radians: Scalar
    x_threshold: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        gravity: ScalarLike = 9.8,
        cart_mass: ScalarLike = 1.0,
        pole_mass: ScalarLike = 0.1,
        half_length: ScalarLike = 0.5,
        force_mag: ScalarLike = 10.0,
        theta_threshold_radians: ScalarLike = 12 * 2 * math.pi / 360,
        x_threshold: ScalarLike = 2.4,
        dt: ScalarLike = 0.02,
        solver: SolverLike = "euler",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 500,
        joint_damping: ScalarLike | None = None,
        end_stop_stiffness: ScalarLike | None = None,
        end_stop_damping: ScalarLike | None = None,
        track_limit: ScalarLike | None = None,
    ):
        (
            self.dynamics, self.integrator, self.dt, self.force_mag,
            self.theta_threshold_radians, self.x_threshold,
        ) = _cartpole_parts(
            gravity, cart_mass, pole_mass, half_length, force_mag, theta_threshold_radians,
            x_threshold, dt, solver, stepsize_controller, joint_damping, end_stop_stiffness,
            end_stop_damping, track_limit,
        )
        self.max_episode_steps = max_episode_steps

    @property
    def action_space(self) -> Discrete:
        return Discrete(2)

    def physical_input(self, action: Array) -> Input:
        return jnp.where(action == 1, self.force_mag, -self.force_mag)[None]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, action, next_state, key
        return jnp.ones((), dtype=self.dt.dtype)


class CartPoleContinuous(AbstractCartPole):
    """CartPole with a continuous force: action `a` in `[-1, 1]` pushes with `a * force_mag` newtons.

    ## Description
    As `CartPole`, with the force chosen continuously.

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range, scaled by `force_mag`.

    ## Observation Space
    `[x, x_dot, theta, theta_dot]`, as `CartPole`.

    ## Rewards
    `reward="gymnasium"` (default): +1 for every step, as `CartPole`.
    `reward="smooth"`: `cos(theta) - action_cost * |u|` with `u` the force in newtons,
    a differentiable reward for gradient-based control.

    ## Starting State
    As `CartPole`.

    ## Episode End
    As `CartPole`; set `theta_threshold_radians` and `x_threshold` to `inf` for an
    unbounded task (swing-up, say).

    ## Arguments
    Those of `CartPole` (the stiff options included), plus `reward` and `action_cost` (>= 0).
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: CartPoleDynamics | ForcedDynamics
    integrator: Integrator
    dt: Scalar
    force_mag: Scalar
    theta_threshold_radians: Scalar
    x_threshold: Scalar
    action_cost: Scalar
    max_episode_steps: int | None = eqx.field(static=True)
    reward_kind: Literal["gymnasium", "smooth"] = eqx.field(static=True)

    def __init__(
        self,
        *,
        gravity: ScalarLike = 9.8,
        cart_mass: ScalarLike = 1.0,
        pole_mass: ScalarLike = 0.1,
        half_length: ScalarLike = 0.5,
        force_mag: ScalarLike = 10.0,
        theta_threshold_radians: ScalarLike = 12 * 2 * math.pi / 360,
        x_threshold: ScalarLike = 2.4,
        dt: ScalarLike = 0.02,
        solver: SolverLike = "euler",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 500,
        reward: Literal["gymnasium", "smooth"] = "gymnasium",
        action_cost: ScalarLike = 1e-3,
        joint_damping: ScalarLike | None = None,
        end_stop_stiffness: ScalarLike | None = None,
        end_stop_damping: ScalarLike | None = None,
        track_limit: ScalarLike | None = None,
    ):
        (
            self.dynamics, self.integrator, self.dt, self.force_mag,
            self.theta_threshold_radians, self.x_threshold,
        ) = _cartpole_parts(
            gravity, cart_mass, pole_mass, half_length, force_mag, theta_threshold_radians,
            x_threshold, dt, solver, stepsize_controller, joint_damping, end_stop_stiffness,
            end_stop_damping, track_limit,
        )
        if reward not in ("gymnasium", "smooth"):
            raise ValueError(f"reward must be 'gymnasium' or 'smooth', got {reward!r}")
        check_nonnegative(action_cost, "action_cost")
        self.action_cost = as_parameter(action_cost, "action_cost")
        self.max_episode_steps = max_episode_steps
        self.reward_kind = reward

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (1,))

    def physical_input(self, action: Array) -> Input:
        return self.force_mag * jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, key
        if self.reward_kind == "gymnasium":
            return jnp.ones((), dtype=self.dt.dtype)
        force = self.physical_input(action)[0]
        return jnp.cos(next_state.y[2]) - self.action_cost * jnp.abs(force)
