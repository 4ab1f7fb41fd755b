from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import POSITIVE, Range, option
from .._types import Array, BoolScalar, Float, Input, Scalar, ScalarLike, State
from .contact import AbstractContact
from .walker import SLOPE, AbstractWalkerDynamics

# Two neighbouring spokes must not both be downhill of the hub, or no stance exists.
HALF_ANGLE = Range(
    "in (0, pi/2) (allowed range (0, pi/2); pi / number of spokes)",
    lambda a: bool(np.all(np.isfinite(a)) and np.all((a > 0) & (a < np.pi / 2))),
)


@final
class RimlessWheelDynamics(AbstractWalkerDynamics):
    """A rimless wheel on a slope: the stance phase, its contact surfaces and its impact map.

    A point mass `mass` at the hub of spokes of length `leg_length`, `2 * spoke_half_angle`
    apart, on a slope of `slope` radians, under `gravity` (Tedrake's *Underactuated
    Robotics*, "Simple models of walking"). State `y = [theta, theta_dot]`: the stance
    spoke's angle from the vertical, positive downhill. In stance the wheel is an inverted
    pendulum about the stance foot, with the ankle torque `u[0]` at the foot:
    `theta'' = (g / l) sin(theta) + u / (m l**2)`.

    The stance ends at a contact of a neighbouring spoke with the slope:
    - heel strike (`front_gap(y) = slope + spoke_half_angle - theta` reaches 0 moving
      downhill): the front spoke becomes the stance spoke, `heel_strike`;
    - rear strike (`rear_gap(y) = theta - slope + spoke_half_angle` reaches 0 moving
      uphill, a wheel that rolled back): the rear spoke becomes the stance spoke,
      `rear_strike`.
    Both impacts are inelastic and conserve the angular momentum about the new contact
    point: `theta_dot+ = cos(2 alpha) theta_dot-`, `theta+ = theta- -+ 2 alpha`.

    The passive wheel (`u = 0`) that passes over the top rolls onto a limit cycle whose
    post-impact speed is `limit_cycle_speed` (see there).

    At rest the wheel stands on two spokes: labelled `theta = slope - alpha`,
    `theta_dot = 0`, held there by the rear spoke while gravity and torque press it
    uphill (`theta'' < 0`), released as soon as they do not. `SpokeContact` leaves a wheel
    slower than its `min_rebound_speed` after an impact in that state.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)
    # The state's components by name, as the docstring writes them (`lerax-like gait` prints them).
    state_names: ClassVar[tuple[str, ...]] = ("theta", "theta_dot")

    leg_length: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # m
    spoke_half_angle: Scalar = eqx.field(default=jnp.pi / 8, converter=HALF_ANGLE)  # rad, half the angle between spokes
    slope: Scalar = eqx.field(default=0.08, converter=SLOPE)  # rad
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)  # m/s^2
    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg, at the hub

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        theta, theta_dot = y
        l = self.leg_length
        theta_acc = self.gravity / l * jnp.sin(theta) + u[0] / (self.mass * l**2)
        # Resting on two spokes: the rear spoke's reaction cancels what presses it in.
        # Exact comparisons: `SpokeContact.impact` sets this state exactly.
        resting = (theta == self.slope - self.spoke_half_angle) & (theta_dot == 0) & (theta_acc < 0)
        return jnp.stack([theta_dot, jnp.where(resting, jnp.zeros_like(theta_acc), theta_acc)])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus potential energy, the height measured from the stance foot.

        Conserved in stance with zero torque, lost at every impact (a factor
        `cos(2 alpha)**2` of the kinetic energy): not a conserved energy of the hybrid flow.
        """
        theta, theta_dot = y
        m, l = self.mass, self.leg_length
        return m * l**2 / 2 * theta_dot**2 + m * self.gravity * l * jnp.cos(theta)

    def front_gap(self, y: State) -> Scalar:
        """The angle the stance spoke may still turn downhill before the front spoke lands."""
        return self.slope + self.spoke_half_angle - y[0]

    def rear_gap(self, y: State) -> Scalar:
        """The angle the stance spoke may still turn uphill before the rear spoke lands."""
        return y[0] - self.slope + self.spoke_half_angle

    def heel_strike(self, y: State) -> State:
        """The state just after the front spoke lands: it is the new stance spoke."""
        theta, theta_dot = y
        alpha = self.spoke_half_angle
        return jnp.stack([theta - 2 * alpha, jnp.cos(2 * alpha) * theta_dot])

    def stance_angle(self, y: State) -> Scalar:
        return y[0] - self.slope

    def hip_speed(self, y: State) -> Scalar:
        return self.leg_length * jnp.cos(y[0] - self.slope) * y[1]

    def rear_strike(self, y: State) -> State:
        """The state just after the rear spoke lands (the wheel rolled back)."""
        theta, theta_dot = y
        alpha = self.spoke_half_angle
        return jnp.stack([theta + 2 * alpha, jnp.cos(2 * alpha) * theta_dot])

    @property
    def limit_cycle_speed(self) -> Scalar:
        """The passive rolling limit cycle's post-impact `theta_dot`, in closed form.

        From `theta+ = slope - alpha` to the next heel strike at `slope + alpha` the hub
        drops by `2 l sin(alpha) sin(slope)`, so energy gives
        `theta_dot-**2 = theta_dot+**2 + 4 (g / l) sin(alpha) sin(slope)`; the impact scales
        the speed by `cos(2 alpha)`. The fixed point is
        `cot(2 alpha) sqrt(4 (g / l) sin(alpha) sin(slope))`, stable (the step map's slope
        is `cos(2 alpha)**2 < 1`) wherever the wheel on it passes over the top
        (`rolls_over_the_top`).
        """
        alpha = self.spoke_half_angle
        drop = 4 * self.gravity / self.leg_length * jnp.sin(alpha) * jnp.sin(self.slope)
        return jnp.sqrt(drop) / jnp.tan(2 * alpha)

    @property
    def speed_to_pass_the_top(self) -> Scalar:
        """The least post-impact `theta_dot` that carries the hub over the stance foot.

        From `theta = slope - alpha` up to `theta = 0` the hub rises by
        `l (1 - cos(slope - alpha))`.
        """
        rise = 1 - jnp.cos(self.slope - self.spoke_half_angle)
        return jnp.sqrt(2 * self.gravity / self.leg_length * rise)

    @property
    def rolls_over_the_top(self) -> BoolScalar:
        """Whether the passive limit cycle exists: its speed carries the wheel over the top."""
        return self.limit_cycle_speed > self.speed_to_pass_the_top


@final
class SpokeContact(AbstractContact):
    """The spokes of a `RimlessWheelDynamics` landing on the slope: a heel strike or a rear strike.

    Gaps `[front_gap, rear_gap]` (radians); the impact swaps the stance spoke
    (`heel_strike`, `rear_strike`), conserving the angular momentum about the new foot. A
    wheel left slower than `min_rebound_speed` (rad/s) comes to rest on two spokes (the
    state `[slope - alpha, 0]`, see `RimlessWheelDynamics`): a wheel rocking between two
    spokes would otherwise strike without end, each impact a factor `cos(2 alpha)` slower
    and sooner. `max_events` bounds the strikes of one env step (a failed step beyond).
    """

    min_rebound_speed: Scalar = eqx.field(default=1e-3, converter=POSITIVE)  # rad/s
    max_events: int = option(32, None)

    def gaps(self, dynamics: RimlessWheelDynamics, y: State) -> Float[Array, " 2"]:
        return jnp.stack([dynamics.front_gap(y), dynamics.rear_gap(y)])

    def impact(self, dynamics: RimlessWheelDynamics, y: State, surface: int) -> State:
        after = dynamics.heel_strike(y) if surface == 0 else dynamics.rear_strike(y)
        rest = jnp.stack([dynamics.slope - dynamics.spoke_half_angle, jnp.zeros_like(after[1])])
        return jnp.where(jnp.abs(after[1]) < self.min_rebound_speed, rest, after)

    def check(self, dynamics) -> None:
        if not isinstance(dynamics, RimlessWheelDynamics):
            raise ValueError(f"SpokeContact lands a rimless wheel's spokes, and {type(dynamics).__name__} is none")
