"""Hold a damped spring-mass at rest at the origin with a bounded force."""

from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import lerax_like as ll
from lerax_like import NONNEGATIVE, POSITIVE, EnvState
from lerax_like.env import episode_limit

from .physics import SpringMassDynamics


_ERROR_CAP = 10.0


@ll.register_scene
@final
class SpringMass(ll.AbstractUnitActionEnv):
    """Hold a damped spring-mass at rest at the origin with a bounded force.

    ## Description
    A mass on a spring with a damper (`SpringMassDynamics`); each step integrates it over
    `dt` with the chosen solver (`"tsit5"` by default).

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range; the force is `force_mag * action` newtons.

    ## Observation Space
    The state `[x, x_dot]`, unbounded.

    ## Rewards
    `-min(x^2 + x_dot^2, 100) - action_cost * a^2` after the step, `a` the clipped action.

    ## Starting State
    `x` and `x_dot` uniform in `(-1, 1)`.

    ## Episode End
    Never terminated but by a failed integration (`info["solver_ok"]`); truncated after
    `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `SpringMassDynamics`) or `mass`, `stiffness`, `damping` flat;
    `force_mag`, `action_cost`, `dt`, `integrator` or `solver`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_size: ClassVar[int] = 1

    dynamics: SpringMassDynamics = eqx.field(default_factory=SpringMassDynamics)
    integrator: ll.Integrator = eqx.field(default="tsit5", converter=ll.make_integrator)
    force_mag: jax.Array = eqx.field(default=1.0, converter=POSITIVE)
    action_cost: jax.Array = eqx.field(default=1e-2, converter=NONNEGATIVE)
    dt: jax.Array = eqx.field(default=0.05, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(200)

    @property
    def initial_bounds(self) -> tuple[jax.Array, jax.Array]:
        return -jnp.ones(2, self.dt.dtype), jnp.ones(2, self.dt.dtype)

    def physical_input(self, action: jax.Array) -> jax.Array:
        return self.force_mag * self.clipped(action)

    def reward(self, state: EnvState, action: jax.Array, next_state: EnvState, *, key: jax.Array | None) -> jax.Array:
        del state, key
        error = jnp.minimum(jnp.sum(next_state.y**2), _ERROR_CAP**2)
        return -error - self.action_cost * jnp.sum(self.clipped(action) ** 2)

    @property
    def worst_reward(self) -> jax.Array:
        return -(_ERROR_CAP**2) - self.action_cost


@ll.gym.register_renderer(SpringMass)
def draw_spring_mass(scene: SpringMass, state, action):
    """Its picture (`lerax_like.gym.render_frame`, `render_mode="rgb_array"`): a block on a
    spring from a wall at 2 m to its left, its rest position marked."""
    canvas = ll.gym.Canvas((-2.5, 2.5), (-1.0, 1.0))
    x = float(state[0])
    canvas.segment((-2.0, -0.5), (-2.0, 0.5), 4.0, (0, 0, 0))
    canvas.segment((-2.5, -0.25), (2.5, -0.25), 2.0, (0, 0, 0))
    canvas.segment((0.0, -0.35), (0.0, -0.15), 2.0, (44, 160, 44))
    coils = np.linspace(-2.0, x - 0.25, 13)
    heights = 0.15 * np.resize([0.0, 1.0, 0.0, -1.0], coils.size)
    for a, b in zip(zip(coils[:-1], heights[:-1]), zip(coils[1:], heights[1:])):
        canvas.segment(a, b, 2.0, (120, 120, 120))
    canvas.rectangle((x - 0.25, -0.25), (x + 0.25, 0.25), (129, 132, 203))
    return canvas.image()
