import math
from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE
from .._types import Array, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.chain import NLinkPendulumDynamics
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv


@register_scene
@final
class NLinkPendulum(AbstractUnitActionEnv):
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
    `dynamics` (an `NLinkPendulumDynamics`) or its parameters flat: `masses` (n,),
    `lengths` (n,) (full lengths), `gravity`. `max_torque` (>= 0), `action_cost`, `dt`,
    `integrator` or `solver` (a preset name or a diffrax solver; default "rk4") with
    `stepsize_controller`, `max_episode_steps`. The number of links n is
    the length of `masses`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_scale: ClassVar[str] = "max_torque"

    dynamics: NLinkPendulumDynamics = eqx.field(default_factory=NLinkPendulumDynamics)
    integrator: Integrator = eqx.field(default="rk4", converter=make_integrator)
    max_torque: Scalar = eqx.field(default=0.0, converter=NONNEGATIVE)
    action_cost: Scalar = eqx.field(default=1e-3, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(500)

    @property
    def n_links(self) -> int:
        return self.dynamics.n_links

    @property
    def action_size(self) -> int:
        return self.n_links

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        # Angles uniform in [-pi, pi), rates in [-0.05, 0.05).
        high = jnp.repeat(jnp.array([math.pi, 0.05], dtype=self.dt.dtype), self.n_links)
        return -high, high

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        clipped = self.clipped(action)
        return jnp.mean(jnp.cos(next_state.y[: self.n_links])) - self.action_cost * jnp.sum(clipped**2)

    @property
    def worst_reward(self) -> Scalar:
        return -1.0 - self.action_cost * self.n_links
