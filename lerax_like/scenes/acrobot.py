import math
from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE, POSITIVE_OR_INF
from .._types import Array, BoolScalar, Input, Key, Scalar, State
from ..env import AbstractEnv, EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics import AcrobotDynamics
from ..spaces import Box, Discrete
from ._registry import register_scene


def _wrap(x: Scalar, low: float, high: float) -> Scalar:
    """Gymnasium's `wrap`: shift `x` by whole periods into `[low, high]`.

    Gymnasium subtracts (or adds) the period in a loop; one shift is `x - period`
    exactly as there, and rarer multiple shifts agree to the ulp.
    """
    period = high - low
    above = jnp.ceil((x - high) / period)
    x = jnp.where(x > high, x - above * period, x)
    below = jnp.ceil((low - x) / period)
    return jnp.where(x < low, x + below * period, x)


@register_scene
@final
class Acrobot(AbstractEnv):
    """Swing the tip of a two-link arm, actuated at the elbow only, above a line (Acrobot-v1).

    ## Description
    Two links hinged in series (`AcrobotDynamics`, Sutton and Barto's "book" equations),
    hanging from a fixed pivot; a torque acts between the links. With `solver="rk4"`
    (the default) a step is Gymnasium's step: one classic Runge--Kutta step over `dt`,
    then the angles are wrapped to `[-pi, pi]` and the angular velocities clipped to
    `max_velocity_1`, `max_velocity_2` (the projection, applied after any solver's step).

    ## Action Space
    `Discrete(3)`: a torque of `-torque`, 0 or `+torque` (N m) at the elbow.

    ## Observation Space
    `[cos(theta_1), sin(theta_1), cos(theta_2), sin(theta_2), theta_1_dot, theta_2_dot]`.

    ## Rewards
    -1 for every step that does not reach the goal, 0 for the step that does.

    ## Starting State
    All four state coordinates uniform in `(-0.1, 0.1)`.

    ## Episode End
    Terminated when the tip is more than one link length above the pivot,
    `-cos(theta_1) - cos(theta_1 + theta_2) > 1`, or when the integration fails.
    Truncated after `max_episode_steps` (500) steps.

    ## Arguments
    `dynamics` (an `AcrobotDynamics`) or its parameters flat (`gravity`, `link_length_1`,
    `link_mass_1`, `link_mass_2`, `link_com_position_1`, `link_com_position_2`,
    `link_moment_of_inertia_1`, `link_moment_of_inertia_2`, `equations`), `torque` (1),
    `max_velocity_1` (4 pi), `max_velocity_2` (9 pi), `dt` (0.2), `integrator` or
    `solver` with `stepsize_controller`, `max_episode_steps`. Gymnasium's optional torque noise
    (`torque_noise_max`, 0 by default there) is not modelled.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: AcrobotDynamics = eqx.field(default_factory=AcrobotDynamics)
    integrator: Integrator = eqx.field(default="rk4", converter=make_integrator)
    torque: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    max_velocity_1: Scalar = eqx.field(default=4 * math.pi, converter=POSITIVE_OR_INF)
    max_velocity_2: Scalar = eqx.field(default=9 * math.pi, converter=POSITIVE_OR_INF)
    dt: Scalar = eqx.field(default=0.2, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(500)

    @property
    def action_space(self) -> Discrete:
        return Discrete(3)

    @property
    def observation_space(self) -> Box:
        one = jnp.ones_like(self.max_velocity_1)
        high = jnp.stack([one, one, one, one, self.max_velocity_1, self.max_velocity_2])
        return Box(-high, high)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        return jnp.full(4, -0.1, self.dt.dtype), jnp.full(4, 0.1, self.dt.dtype)

    def physical_input(self, action: Array) -> Input:
        return ((jnp.asarray(action).astype(self.torque.dtype) - 1.0) * self.torque)[None]

    def project(self, y: State) -> State:
        theta_1, theta_2, dtheta_1, dtheta_2 = y
        return jnp.stack(
            [
                _wrap(theta_1, -math.pi, math.pi),
                _wrap(theta_2, -math.pi, math.pi),
                jnp.clip(dtheta_1, -self.max_velocity_1, self.max_velocity_1),
                jnp.clip(dtheta_2, -self.max_velocity_2, self.max_velocity_2),
            ]
        )

    def observation(self, state: EnvState, *, key: Key | None) -> Array:
        del key
        theta_1, theta_2, dtheta_1, dtheta_2 = state.y
        return jnp.stack(
            [jnp.cos(theta_1), jnp.sin(theta_1), jnp.cos(theta_2), jnp.sin(theta_2), dtheta_1, dtheta_2]
        )

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, action
        return jnp.where(self.terminal(next_state, key=key), 0.0, -1.0).astype(self.dt.dtype)

    @property
    def worst_reward(self) -> Scalar:
        return -jnp.ones((), dtype=self.dt.dtype)

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        del key
        theta_1, theta_2 = state.y[0], state.y[1]
        return -jnp.cos(theta_1) - jnp.cos(theta_2 + theta_1) > 1.0
