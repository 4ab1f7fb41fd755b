import math
from typing import TYPE_CHECKING, ClassVar, final

import jax.numpy as jnp

from .._fields import NONNEGATIVE, parameter
from .._types import Array, Key, Scalar
from ..env import EnvState, dynamics, episode_limit, integrator, time_step
from ..integrate import Integrator
from ..physics.chain import NLinkPendulumDynamics
from ._unit_action import AbstractUnitActionEnv


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

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import IntegratorKeywords, NLinkPendulumDynamicsKeywords
        from lerax_like._types import ScalarLike

        class _Keywords(NLinkPendulumDynamicsKeywords, IntegratorKeywords, total=False): ...

        def __init__(
            self,
            *,
            dynamics: NLinkPendulumDynamics = ...,
            max_torque: ScalarLike = 0.0,
            action_cost: ScalarLike = 0.001,
            dt: ScalarLike = 0.02,
            max_episode_steps: int | None = 500,
            **keywords: Unpack[_Keywords],
        ) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    stochastic: ClassVar[bool] = False  # nothing random but the start
    action_scale: ClassVar[str] = "max_torque"

    dynamics: NLinkPendulumDynamics = dynamics(NLinkPendulumDynamics)
    integrator: Integrator = integrator("rk4")
    max_torque: Scalar = parameter(0.0, NONNEGATIVE)
    action_cost: Scalar = parameter(1e-3, NONNEGATIVE)
    dt: Scalar = time_step(0.02)
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
