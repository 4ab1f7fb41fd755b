from typing import final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE, Range
from .._types import Array, Scalar
from ..env import episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.simplest_walker import SimplestWalkerDynamics
from ..physics.walker import HeelStrike
from ._registry import register_scene
from ._walker import AbstractWalkerEnv

FALL_ANGLE = Range("in (0, pi/2] (allowed range (0, pi/2], radians)", lambda a: bool((a > 0) & (a <= jnp.pi / 2)))


@register_scene
@final
class SimplestWalker(AbstractWalkerEnv):
    """Walk the simplest walker down its slope at a target speed with a bounded ankle torque.

    ## Description
    The simplest walking model of Garcia, Chatterjee, Ruina and Coleman (1998),
    nondimensional (`SimplestWalkerDynamics`): a point mass at the hip on two rigid
    massless legs, on a slope of `slope` radians (0.009, the paper's). Each heel strike is
    located as an event within the step and followed by the impact map and the legs'
    exchange (`HeelStrike`, `lerax_like.hybrid`); the swing foot's scuffing at mid-stance
    is ignored, as in the paper. Passive, near its gait, it walks: at the default slope
    the long-period gait is stable (`lerax_like.analysis.gait`, `lerax-like gait
    SimplestWalker`).

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range: the ankle torque `max_torque * a` (units of
    `M g l`) at the stance foot, positive downhill.

    ## Observation Space
    `[theta, phi, theta_dot, phi_dot]`, the paper's: the stance leg's angle from the slope's
    normal (positive uphill), the angle from the stance leg to the swing leg, and their
    rates (time in units of `sqrt(l / g)`).

    ## Rewards
    `-min((v - target_speed)**2, max_cost) - action_cost * a**2` after the step, `v` the
    hip's speed along the slope (units of `sqrt(g l)`).

    ## Starting State
    Uniform in a box about the paper's stable gait at gamma = 0.009 just after a heel
    strike, `theta` in `[0.195, 0.205]`, `theta_dot` in `[-0.205, -0.195]`, `phi` about
    `2 theta` and `phi_dot` about `(1 - cos 2 theta) theta_dot`.

    ## Episode End
    Terminated when the walker falls (the stance leg at `fall_angle` or more from the
    normal) or the integration fails (`info["solver_ok"]`). Truncated after
    `max_episode_steps` (1000) steps.

    ## Arguments
    `dynamics` (a `SimplestWalkerDynamics`) or its parameter flat: `slope` (0.009). The
    contact (`contacts`, a `HeelStrike`) or its `max_events` (8) flat. `max_torque` (0.01),
    `target_speed` (0.2), `max_cost`, `action_cost`, `fall_angle` (pi / 2), `dt` (0.1),
    `integrator` or `solver` (default `"tsit5"`) with `stepsize_controller`,
    `max_episode_steps`.
    """

    dynamics: SimplestWalkerDynamics = eqx.field(default_factory=SimplestWalkerDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    contacts: tuple = eqx.field(default_factory=lambda: (HeelStrike(),))
    max_torque: Scalar = eqx.field(default=0.01, converter=POSITIVE)  # in units of m g l
    target_speed: Scalar = eqx.field(default=0.2, converter=NONNEGATIVE)  # in units of sqrt(g l)
    max_cost: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    action_cost: Scalar = eqx.field(default=0.01, converter=NONNEGATIVE)
    fall_angle: Scalar = eqx.field(default=jnp.pi / 2, converter=FALL_ANGLE)  # rad
    dt: Scalar = eqx.field(default=0.1, converter=POSITIVE)  # in units of sqrt(l / g)
    max_episode_steps: int | None = episode_limit(1000)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        dtype = self.dt.dtype
        low = jnp.asarray([0.195, 0.39, -0.205, -0.0166], dtype)
        high = jnp.asarray([0.205, 0.41, -0.195, -0.0150], dtype)
        return low, high
