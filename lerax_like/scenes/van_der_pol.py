from typing import ClassVar

import diffrax
import equinox as eqx
import jax.numpy as jnp

from .._checks import as_parameter, check_nonnegative, check_positive
from .._random import uniform
from .._types import Array, BoolScalar, Input, Key, Scalar, ScalarLike
from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, make_integrator
from ..physics import VanDerPolDynamics
from ..spaces import Box


class VanDerPol(AbstractEnv):
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
    `-(r - target_amplitude)^2 - action_cost * action^2` with `r = sqrt(x^2 + v^2)` the
    distance from the origin in the phase plane, evaluated after the step.

    ## Starting State
    `x` and `v` uniform in `(-0.5, 0.5)`: near the unstable equilibrium at the origin.

    ## Episode End
    No task termination: the episode ends when the integration fails (`info["solver_ok"]`
    False, terminated) or is truncated after `max_episode_steps` (200) steps.

    ## Arguments
    `mu` (>= 0), `force_mag` (> 0), `target_amplitude` (> 0), `action_cost` (>= 0),
    `dt` (> 0), `solver` (a preset name, a diffrax solver or an `Integrator`; default
    `"tsit5"`, use `"kvaerno5"` from `mu` of about 100), `stepsize_controller`,
    `max_episode_steps`.
    """

    stochastic: ClassVar[bool] = False  # nothing random but the start

    dynamics: VanDerPolDynamics
    integrator: Integrator
    dt: Scalar
    force_mag: Scalar
    target_amplitude: Scalar
    action_cost: Scalar
    max_episode_steps: int | None = eqx.field(static=True)

    def __init__(
        self,
        *,
        mu: ScalarLike = 1.0,
        force_mag: ScalarLike = 1.0,
        target_amplitude: ScalarLike = 1.0,
        action_cost: ScalarLike = 1e-2,
        dt: ScalarLike = 0.05,
        solver: "str | diffrax.AbstractSolver | Integrator" = "tsit5",
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        max_episode_steps: int | None = 200,
    ):
        check_positive(force_mag, "force_mag")
        check_positive(target_amplitude, "target_amplitude")
        check_nonnegative(action_cost, "action_cost")
        check_positive(dt, "dt")
        self.dynamics = VanDerPolDynamics(mu=mu)
        self.integrator = make_integrator(solver, stepsize_controller)
        self.dt = as_parameter(dt, "dt")
        self.force_mag = as_parameter(force_mag, "force_mag")
        self.target_amplitude = as_parameter(target_amplitude, "target_amplitude")
        self.action_cost = as_parameter(action_cost, "action_cost")
        self.max_episode_steps = max_episode_steps

    @property
    def action_space(self) -> Box:
        return Box(-1.0, 1.0, (1,))

    @property
    def observation_space(self) -> Box:
        return Box(-jnp.inf, jnp.inf, (2,))

    def initial(self, *, key: Key) -> EnvState:
        y = uniform(key, (2,), self.dt.dtype, -0.5, 0.5)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

    def physical_input(self, action: Array) -> Input:
        return self.force_mag * jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0)

    def observation(self, state: EnvState, *, key: Key) -> Array:
        del key
        return state.y

    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key) -> Scalar:
        del state, key
        x, v = next_state.y
        radius = jnp.sqrt(x**2 + v**2)
        effort = jnp.sum(jnp.clip(jnp.reshape(action, (1,)), -1.0, 1.0) ** 2)
        return -((radius - self.target_amplitude) ** 2) - self.action_cost * effort

    def terminal(self, state: EnvState, *, key: Key) -> BoolScalar:
        del state, key
        return jnp.asarray(False)
