import math
from typing import ClassVar, Literal, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE, POSITIVE_OR_INF, option
from .._types import Array, BoolScalar, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.chain import CartChainDynamics
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv
from .cartpole import CART_ADDONS


@register_scene
@final
class DoubleCartPole(AbstractUnitActionEnv):
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
    `task` ("balance" or "swing_up"), `dynamics` (a two-pole `CartChainDynamics`) or its
    parameters flat: `cart_mass`, `pole_masses` (2,), `pole_lengths` (2,) (full lengths),
    `gravity`. `force_mag`, `theta_threshold_radians` (12 degrees), `x_threshold` (2.4 m
    for balance, `inf` for swing-up unless given), `action_cost`, `dt`, `integrator` or
    `solver` (a preset name or a diffrax solver; default "rk4") with
    `stepsize_controller`, `max_episode_steps`. Add-ons (absent unless given, see
    `lerax_like.physics.forces`): `joint_damping` (every joint's damper acts on the rate
    of its two neighbours, the cart being the first pole's); the rail's ends at
    `track_limit`, either as walls located as events (`restitution`, with
    `min_rebound_speed` and `max_events`: an impulse-consistent impact, both poles' rates
    jump) or as penalty end stops (`end_stop_stiffness`, `end_stop_damping`), as `CartPole`.
    Coulomb friction of the cart on its rail (`cart_static_friction`, `cart_kinetic_friction`),
    stick and slip located as events, as `CartPole`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    addons: ClassVar[tuple[type, ...]] = CART_ADDONS
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "force_mag"

    task: Literal["balance", "swing_up"] = option("balance", ("balance", "swing_up"))
    dynamics: CartChainDynamics = eqx.field(default_factory=CartChainDynamics)
    integrator: Integrator = eqx.field(default="rk4", converter=make_integrator)
    forces: tuple = ()  # the add-ons of a cart on a rail (`CART_ADDONS`), as `CartPole`'s
    contacts: tuple = ()
    friction: tuple = ()
    force_mag: Scalar = eqx.field(default=20.0, converter=POSITIVE)  # N
    theta_threshold_radians: Scalar = eqx.field(default=12 * 2 * math.pi / 360, converter=POSITIVE_OR_INF)  # rad
    x_threshold: Scalar = eqx.field(default=None, converter=POSITIVE_OR_INF)  # m; None: the task's
    action_cost: Scalar = eqx.field(default=1e-3, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(500)

    def __post_init__(self):
        if self.x_threshold is None:  # 2.4 m for balance; unbounded for a swing-up
            self.x_threshold = 2.4 if self.task == "balance" else math.inf

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        centre = jnp.zeros(6, self.dt.dtype)
        if self.task == "swing_up":
            centre = centre.at[1:3].set(math.pi)
        return centre - 0.05, centre + 0.05

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        if self.task == "balance":
            return jnp.ones((), dtype=self.dt.dtype)
        clipped = self.clipped(action)[0]
        _, theta1, theta2 = next_state.y[:3]
        return (jnp.cos(theta1) + jnp.cos(theta2)) / 2 - self.action_cost * clipped**2

    @property
    def worst_reward(self) -> Scalar:
        if self.task == "balance":
            return jnp.ones((), dtype=self.dt.dtype)
        return -1.0 - self.action_cost

    def __check_init__(self):
        if self.dynamics.n_links != 2:
            raise ValueError(
                f"pole_masses and pole_lengths must have shape (2,), got {self.dynamics.pole_masses.shape}"
            )

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
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
