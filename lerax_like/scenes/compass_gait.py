from typing import final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE
from .._types import Array, Scalar
from ..env import episode_limit
from ..integrate import Integrator, make_integrator
from ..physics.compass_gait import CompassGaitDynamics
from ..physics.walker import HeelStrike
from ._registry import register_scene
from ._walker import AbstractWalkerEnv
from .simplest_walker import FALL_ANGLE


@register_scene
@final
class CompassGait(AbstractWalkerEnv):
    """Walk the compass-gait biped down its slope at a target speed with a bounded hip torque.

    ## Description
    The compass-like biped of Goswami, Thuilot and Espiau (INRIA RR-2996, 1996;
    `CompassGaitDynamics`): two rigid legs with point masses `leg_mass` at `lower_length`
    from the foot and `upper_length` from the hip, and a hip mass `hip_mass`, on a slope of
    `slope` radians (defaults the report's nominal walker: a = b = 0.5 m, m = 5 kg,
    m_H = 10 kg, 3 degrees). Each heel strike is located as an event within the step and
    followed by the momentum-conserving impact map and the legs' exchange (`HeelStrike`,
    `lerax_like.hybrid`); the swing foot's scuffing at mid-stance is ignored, as in the
    report. Passive, near its gait, it walks: at the nominal slope its period-one gait is
    stable (`lerax_like.analysis.gait`, `lerax-like gait CompassGait`).

    ## Action Space
    `Box(-1, 1, (1,))`, clipped to that range: the hip torque `max_torque * a` (N m) on the
    swing leg, positive downhill, its reaction on the stance leg.

    ## Observation Space
    `[theta_s, theta_w, theta_s_dot, theta_w_dot]`: the stance and swing legs' angles from
    the vertical (foot to hip, positive downhill; rad) and their rates (rad/s).

    ## Rewards
    `-min((v - target_speed)**2, max_cost) - action_cost * a**2` after the step, `v` the
    hip's speed along the slope (m/s).

    ## Starting State
    Uniform in a box about the nominal passive gait just after a heel strike (angles
    within 0.005 rad, rates within 0.02 rad/s of `[-0.2187, 0.3234, 1.0924, 0.3774]`).

    ## Episode End
    Terminated when the walker falls (the stance leg at `fall_angle` or more from the
    slope's normal) or the integration fails (`info["solver_ok"]`). Truncated after
    `max_episode_steps` (1000) steps.

    ## Arguments
    `dynamics` (a `CompassGaitDynamics`) or its parameters flat: `lower_length` (0.5),
    `upper_length` (0.5), `leg_mass` (5), `hip_mass` (10), `slope` (3 degrees in radians),
    `gravity` (9.81). The contact (`contacts`, a `HeelStrike`) or its `max_events` (8)
    flat. `max_torque` (1), `target_speed` (1 m/s), `max_cost`, `action_cost`,
    `fall_angle` (pi / 2), `dt` (0.02), `integrator` or `solver` (default `"tsit5"`) with
    `stepsize_controller`, `max_episode_steps`.
    """

    dynamics: CompassGaitDynamics = eqx.field(default_factory=CompassGaitDynamics)
    integrator: Integrator = eqx.field(default="tsit5", converter=make_integrator)
    contacts: tuple = eqx.field(default_factory=lambda: (HeelStrike(),))
    max_torque: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # N m, at the hip
    target_speed: Scalar = eqx.field(default=1.0, converter=NONNEGATIVE)  # m/s along the slope
    max_cost: Scalar = eqx.field(default=4.0, converter=POSITIVE)
    action_cost: Scalar = eqx.field(default=0.01, converter=NONNEGATIVE)
    fall_angle: Scalar = eqx.field(default=jnp.pi / 2, converter=FALL_ANGLE)  # rad
    dt: Scalar = eqx.field(default=0.02, converter=POSITIVE)  # s
    max_episode_steps: int | None = episode_limit(1000)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        gait = jnp.asarray([-0.2187, 0.3234, 1.0924, 0.3774], self.dt.dtype)
        spread = jnp.asarray([0.005, 0.005, 0.02, 0.02], self.dt.dtype)
        return gait - spread, gait + spread
