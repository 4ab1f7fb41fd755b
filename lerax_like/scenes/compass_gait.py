from typing import TYPE_CHECKING, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE, parameter
from .._types import Array, Scalar
from ..env import dynamics, episode_limit, integrator, time_step
from ..integrate import Integrator
from ..physics.compass_gait import CompassGaitDynamics
from ..physics.walker import HeelStrike
from ._walker import AbstractWalkerEnv
from .simplest_walker import FALL_ANGLE


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

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import CompassGaitDynamicsKeywords, HeelStrikeKeywords, IntegratorKeywords
        from lerax_like._types import ScalarLike

        class _Keywords(CompassGaitDynamicsKeywords, IntegratorKeywords, HeelStrikeKeywords, total=False): ...

        def __init__(
            self,
            *,
            dynamics: CompassGaitDynamics = ...,
            contacts: tuple = ...,
            max_torque: ScalarLike = 1.0,
            target_speed: ScalarLike = 1.0,
            max_cost: ScalarLike = 4.0,
            action_cost: ScalarLike = 0.01,
            fall_angle: ScalarLike = 1.5707963267948966,
            dt: ScalarLike = 0.02,
            max_episode_steps: int | None = 1000,
            **keywords: Unpack[_Keywords],
        ) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    dynamics: CompassGaitDynamics = dynamics(CompassGaitDynamics)
    integrator: Integrator = integrator("tsit5")
    contacts: tuple = eqx.field(default_factory=lambda: (HeelStrike(),))
    max_torque: Scalar = parameter(1.0, POSITIVE)
    target_speed: Scalar = parameter(1.0, NONNEGATIVE)
    max_cost: Scalar = parameter(4.0, POSITIVE)
    action_cost: Scalar = parameter(0.01, NONNEGATIVE)
    fall_angle: Scalar = parameter(jnp.pi / 2, FALL_ANGLE)
    dt: Scalar = time_step(0.02)
    max_episode_steps: int | None = episode_limit(1000)

    @property
    def initial_bounds(self) -> tuple[Array, Array]:
        gait = jnp.asarray([-0.2187, 0.3234, 1.0924, 0.3774], self.dt.dtype)
        spread = jnp.asarray([0.005, 0.005, 0.02, 0.02], self.dt.dtype)
        return gait - spread, gait + spread
