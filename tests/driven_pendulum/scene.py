"""Keep a driven damped pendulum near the bottom with a bounded extra torque."""

import math
from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp

import lerax_like as ll
from lerax_like import NONNEGATIVE, POSITIVE, EnvState
from lerax_like.env import episode_limit

from .physics import DrivenPendulumDynamics


_ERROR_CAP = 100.0


@ll.register_scene
@final
class DrivenPendulum(ll.AbstractUnitActionEnv):
    """Keep a driven damped pendulum near the bottom with a bounded extra torque.

    ## Description
    A damped pendulum under the periodic drive `drive_amplitude cos(drive_frequency t)`
    (`DrivenPendulumDynamics`), `t` the episode's time; each step integrates it over `dt`.

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range; the extra torque is `torque_mag * action`.

    ## Observation Space
    The state `[theta, theta_dot]`, unbounded.

    ## Rewards
    `-min(theta^2 + theta_dot^2, 100) - action_cost * a^2` after the step, `a` the clipped action.

    ## Starting State
    `theta` and `theta_dot` uniform in `(-0.5, 0.5)`.

    ## Episode End
    Never terminated but by a failed integration (`info["solver_ok"]`); truncated after
    `max_episode_steps` (300) steps.

    ## Arguments
    `dynamics` (a `DrivenPendulumDynamics`) or `natural_frequency`, `damping`,
    `drive_amplitude`, `drive_frequency` flat; `torque_mag`, `action_cost`, `dt`,
    `integrator` or `solver`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "torque_mag"

    dynamics: DrivenPendulumDynamics = eqx.field(default_factory=DrivenPendulumDynamics)
    integrator: ll.Integrator = eqx.field(default="rk4", converter=ll.make_integrator)
    torque_mag: jax.Array = eqx.field(default=0.5, converter=POSITIVE)
    action_cost: jax.Array = eqx.field(default=1e-2, converter=NONNEGATIVE)
    dt: jax.Array = eqx.field(default=0.05, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(300)

    @property
    def initial_bounds(self) -> tuple[jax.Array, jax.Array]:
        return -0.5 * jnp.ones(2, self.dt.dtype), 0.5 * jnp.ones(2, self.dt.dtype)

    def reward(self, state: EnvState, action: jax.Array, next_state: EnvState, *, key: jax.Array | None) -> jax.Array:
        del state, key
        error = jnp.minimum(jnp.sum(next_state.y**2), _ERROR_CAP)
        return -error - self.action_cost * jnp.sum(self.clipped(action) ** 2)

    @property
    def worst_reward(self) -> jax.Array:
        return -_ERROR_CAP - self.action_cost


@ll.gym.register_renderer(DrivenPendulum)
def draw_driven_pendulum(scene: DrivenPendulum, state, action):
    """Its picture (`lerax_like.gym.render_frame`): a rod of unit length hanging from its pivot
    at angle `theta` from the downward vertical."""
    canvas = ll.gym.Canvas((-1.5, 1.5), (-1.25, 0.75))
    theta = float(state[0])
    bob = (math.sin(theta), -math.cos(theta))
    canvas.segment((0.0, 0.0), bob, 8.0, (202, 152, 101))
    canvas.disc(bob, 10.0, (129, 132, 203))
    canvas.disc((0.0, 0.0), 4.0, (0, 0, 0))
    return canvas.image()
