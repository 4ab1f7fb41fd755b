import math
from typing import ClassVar, Literal, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE, POSITIVE_OR_INF, option
from .._types import Array, BoolScalar, Input, Key, Scalar
from ..env import AbstractEnv, EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics import CartPoleDynamics
from ..physics.contact import Walls
from ..physics.forces import EndStops, JointDamping
from ..physics.friction import CartFriction
from ..spaces import Box, Discrete
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv

_TWELVE_DEGREES = 12 * 2 * math.pi / 360
# The add-ons of a cart on a rail, whatever it carries (`DoubleCartPole` takes them too): the
# joints' damping, the track's soft end stops or rigid walls, the rail's dry friction.
CART_ADDONS: tuple[type, ...] = (JointDamping, EndStops, Walls, CartFriction)


class AbstractCartPole(AbstractEnv):
    """What the discrete and continuous cart-poles share: physics, add-ons, start, observation, end.

    The fields both declare are declared here, once; each concrete cart-pole adds the
    fields of its own action and reward.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    addons: ClassVar[tuple[type, ...]] = CART_ADDONS

    dynamics: CartPoleDynamics = eqx.field(default_factory=CartPoleDynamics)
    integrator: Integrator = eqx.field(default="euler", converter=make_integrator)
    forces: tuple = ()
    contacts: tuple = ()
    friction: tuple = ()
    force_mag: Scalar = eqx.field(default=10.0, converter=POSITIVE)  # N
    theta_threshold_radians: Scalar = eqx.field(default=_TWELVE_DEGREES, converter=POSITIVE_OR_INF)  # rad
    x_threshold: Scalar = eqx.field(default=2.4, converter=POSITIVE_OR_INF)  # m
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(500)

    @property
    def observation_space(self) -> Box:
        high = jnp.stack([2 * self.x_threshold, jnp.inf, 2 * self.theta_threshold_radians, jnp.inf])
        return Box(-high, high)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        return jnp.full(4, -0.05, self.dt.dtype), jnp.full(4, 0.05, self.dt.dtype)

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        x, _, theta, _ = state.y
        return (
            (x < -self.x_threshold)
            | (x > self.x_threshold)
            | (theta < -self.theta_threshold_radians)
            | (theta > self.theta_threshold_radians)
        )


@register_scene
@final
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
    +1 for every step, the terminating step included. With `sutton_barto_reward=True`
    (Gymnasium's keyword), as in Sutton and Barto's book: 0 for every step, -1 for the
    terminating one.

    ## Starting State
    All four coordinates uniform in `(-0.05, 0.05)`.

    ## Episode End
    Terminated when `|theta| > theta_threshold_radians` (12 degrees) or
    `|x| > x_threshold` (2.4 m), or when the integration fails (`info["solver_ok"]`).
    Truncated after `max_episode_steps` (500) steps.

    ## Arguments
    `dynamics` (a `CartPoleDynamics`), or its parameters flat: `gravity`, `cart_mass`,
    `pole_mass`, `half_length`. `force_mag`, `theta_threshold_radians`, `x_threshold`,
    `dt`, `integrator` or `solver` (a preset name or a diffrax solver) with
    `stepsize_controller`, `max_episode_steps`, `sutton_barto_reward` (False).
    Add-ons of real rigs, absent unless given (see `lerax_like.physics.forces`):
    `joint_damping` (hinge friction, N m s/rad; 300 is very stiff). The ends of the rail,
    at `x = +-track_limit` (set `x_threshold=inf` to let the cart reach them), two ways:
    - `restitution` (in [0, 1]) selects rigid walls located as events (`Walls`,
      `lerax_like.physics.contact`): the solver stops at the impact time, reverses the
      cart's speed times `restitution`, impulse-consistently (the pole's rate jumps too),
      and goes on; with `min_rebound_speed` (below which the cart rests against the wall)
      and `max_events` (impacts per step; more is a failed step). Exact impact times,
      no penetration, gradients that match finite differences; use a solver of several
      stages (`"tsit5"`, `"rk4"`): the impacts are located on its dense output.
    - `end_stop_stiffness` (up to 1e6 N/m) with `end_stop_damping` selects the penalty
      `EndStops`, one-sided spring-dampers: a soft contact that penetrates, whose
      stiffness forces many small steps (use `"tsit5"` or `"kvaerno5"`) and whose
      gradients are biased after an impact.
    Coulomb friction of the cart on its rail (`CartFriction`, `lerax_like.physics.friction`):
    `cart_static_friction` and `cart_kinetic_friction` (Barto et al.'s 0.0005 for one not
    given; both zero build none), with `max_events`; stick and slip are modes of the step and
    each switch is located (`lerax_like.stick_slip`, the page docs/friction.md), the normal
    force read off the pole's motion (Florian's correction: it may change sign). Barto's
    viscous pole friction is `joint_damping`. Not together with `restitution` walls.
    Stiff settings need an adaptive solver (`"tsit5"`) or an implicit one (`"kvaerno5"`).
    """

    sutton_barto_reward: bool = option(False, (False, True))

    @property
    def action_space(self) -> Discrete:
        return Discrete(2)

    def physical_input(self, action: Array) -> Input:
        return jnp.where(action == 1, self.force_mag, -self.force_mag)[None]

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, action
        if self.sutton_barto_reward:
            return jnp.where(self.terminal(next_state, key=key), -1.0, 0.0).astype(self.dt.dtype)
        return jnp.ones((), dtype=self.dt.dtype)

    @property
    def worst_reward(self) -> Scalar:
        if self.sutton_barto_reward:
            return -jnp.ones((), dtype=self.dt.dtype)
        return jnp.ones((), dtype=self.dt.dtype)


@register_scene
@final
class CartPoleContinuous(AbstractCartPole, AbstractUnitActionEnv):
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
    Those of `CartPole` (the add-ons included), plus `reward` and `action_cost` (>= 0).
    """

    # `reward` is the keyword users know; the field is `reward_kind`, as `reward` is the method.
    aliases: ClassVar[tuple[tuple[str, str], ...]] = (("reward", "reward_kind"),)
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "force_mag"

    action_cost: Scalar = eqx.field(default=1e-3, converter=NONNEGATIVE)
    reward_kind: Literal["gymnasium", "smooth"] = option("gymnasium", ("gymnasium", "smooth"))

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        if self.reward_kind == "gymnasium":
            return jnp.ones((), dtype=self.dt.dtype)
        force = self.physical_input(action)[0]
        return jnp.cos(next_state.y[2]) - self.action_cost * jnp.abs(force)

    @property
    def worst_reward(self) -> Scalar:
        if self.reward_kind == "gymnasium":
            return jnp.ones((), dtype=self.dt.dtype)
        return -1.0 - self.action_cost * self.force_mag
