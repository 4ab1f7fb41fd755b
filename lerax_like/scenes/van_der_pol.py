from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE
from .._types import Array, Key, Scalar
from ..env import EnvState, episode_limit
from ..integrate import Integrator, make_integrator
from ..physics import VanDerPolDynamics
from ._registry import register_scene
from ._unit_action import AbstractUnitActionEnv

_ERROR_CAP = 100.0


@register_scene
@final
class VanDerPol(AbstractUnitActionEnv):
    """Hold a forced Van der Pol oscillator at a target amplitude; stiff for large `mu`.

    ## Description
    The physics is `VanDerPolDynamics`: `x' = v`, `v' = mu (1 - x^2) v - x + u`. Unforced,
    every trajectory but the origin's is drawn to a limit cycle of amplitude about 2. The
    task is to hold the oscillation at `target_amplitude` instead, with a bounded force.
    At `mu = 1e3` the problem is the classic stiff test case: explicit solvers exhaust
    their step budget (reported as `info["solver_ok"] = False`), while `solver="kvaerno5"`
    takes env steps of `dt = 10` in a few dozen steps each.

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range; the force is `u = force_mag * action`.

    ## Observation Space
    `[x, v]`, unbounded: position and velocity of the oscillator. For large `mu` the
    velocity reaches about `mu` during the fast jumps of the relaxation oscillation.

    ## Rewards
    `-min(|r - target_amplitude|, 100)^2 - action_cost * action^2` with
    `r = sqrt(x^2 + v^2)` the distance from the origin in the phase plane, evaluated after
    the step. The amplitude error saturates at 100 (far beyond any state a controlled run
    reaches), so that the rewards are bounded below by `-(1e4 + action_cost)`, which a
    failed step pays.

    ## Starting State
    `x` and `v` uniform in `(-0.5, 0.5)`: near the unstable equilibrium at the origin.

    ## Episode End
    No task termination: the episode ends when the integration fails (`info["solver_ok"]`
    False, terminated) or is truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `dynamics` (a `VanDerPolDynamics`) or `mu` (>= 0) flat, `force_mag` (> 0),
    `target_amplitude` (> 0), `action_cost` (>= 0), `dt` (> 0), `integrator` or `solver`
    (a preset name or a diffrax solver; default `"tsit5"`, use `"kvaerno5"` from `mu` of
    about 100) with `stepsize_controller`, `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start
    # Stiff from mu of about 100: the studies take their reference from SciPy's Radau.
    stiff: ClassVar[bool] = True
    action_size: ClassVar[int] = 1
    action_scale: ClassVar[str] = "force_mag"

    dynamics: VanDerPolDynamics = eqx.field(default_factory=VanDerPolDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    force_mag: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    target_amplitude: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # in the phase plane
    action_cost: Scalar = eqx.field(default=1e-2, converter=NONNEGATIVE)
    dt: Scalar = eqx.field(default=0.05, converter=POSITIVE)
    max_episode_steps: int | None = episode_limit(200)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        corner = jnp.full(2, 0.5, self.dt.dtype)
        return -corner, corner

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        del state, key
        x, v = next_state.y
        radius = jnp.sqrt(x**2 + v**2)
        error = jnp.minimum(jnp.abs(radius - self.target_amplitude), _ERROR_CAP)
        return -(error**2) - self.action_cost * self.effort(action)

    @property
    def worst_reward(self) -> Scalar:
        return -(_ERROR_CAP**2) - self.action_cost
