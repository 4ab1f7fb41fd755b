"""A disk in the vertical plane on a floor: its flight, its rolling and sliding, and its impacts with friction.

Angles are measured clockwise, so that rolling forward (to `+x`) is `x_dot = radius *
angle_dot`, and the contact point's slip velocity is `w = x_dot - radius * angle_dot`.
A horizontal force `F` on the floor's contact point (a friction force) pushes the centre by
`F / mass` and turns the disk by `-radius * F / I` (clockwise positive); the motor's torque
`u[0]` turns it by `u[0] / I`.

The pure physics lives here: `RollingDiskDynamics` (parameters and the vector field of each
contact mode) and `DiskFloor` (the floor's friction and restitution, the impact map). The
step that integrates the modes and locates their switches is `lerax_like.floor_contact`.
"""

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE, AbstractParametrised, option
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics
from .contact import RESTITUTION
from .friction import check_coulomb


@final
class RollingDiskDynamics(AbstractConservativeDynamics):
    """A disk of `radius` and `mass`, moment of inertia `inertia_factor * mass * radius**2`, under `gravity`.

    State `y = [x, z, angle, x_dot, z_dot, angle_dot]` (m, rad clockwise, and their rates;
    `z` is the centre's height, the floor at `z = 0`, so the disk touches it at `z = radius`);
    input `u = [torque]` (N m, clockwise). `inertia_factor`: 0.5 a uniform disk, 1 a hoop,
    0.4 a sphere's section. `vector_field` is the free flight; the contact modes are
    `sliding_vector_field` (a given friction force) and `rolling_vector_field` (no slip).
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (3, 4, 5)

    radius: Scalar = eqx.field(default=0.1, converter=POSITIVE)
    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    inertia_factor: Scalar = eqx.field(default=0.5, converter=POSITIVE)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    @property
    def inertia(self) -> Scalar:
        """The moment of inertia about the centre, `inertia_factor * mass * radius**2`."""
        return self.inertia_factor * self.mass * self.radius**2

    def coordinates(self, y: State) -> tuple[Float[Array, " 3"], Float[Array, " 3"]]:
        return y[:3], y[3:]

    def slip_velocity(self, y: State) -> Scalar:
        """The contact point's velocity along the floor, `x_dot - radius * angle_dot` (0: rolling)."""
        return y[3] - self.radius * y[5]

    def normal_force(self) -> Scalar:
        """The floor's normal force on a disk in contact: its weight (nothing else acts vertically)."""
        return self.mass * self.gravity

    def sliding_vector_field(self, t: ScalarLike, y: State, u: Input, friction_force: ScalarLike) -> State:
        """In contact, the floor pushing the contact point by `friction_force` (N) along `x`."""
        del t
        zero = jnp.zeros_like(y[0])
        angular = (u[0] - self.radius * friction_force) / self.inertia
        return jnp.stack([y[3], zero, y[5], friction_force / self.mass + zero, zero, angular])

    def rolling_vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        """In contact without slip: `angle'' = torque / (I + m r^2)`, and `x'' = r angle''` exactly,
        so that the slip velocity's rate is exactly zero."""
        del t
        zero = jnp.zeros_like(y[0])
        angular = u[0] / (self.inertia + self.mass * self.radius**2) + zero
        return jnp.stack([y[3], zero, y[5], self.radius * angular, zero, angular])

    def holding_force(self, u: Input) -> Scalar:
        """The friction force that rolling without slip needs under the torque: `m r torque / (I + m r^2)`."""
        return self.mass * self.radius * u[0] / (self.inertia + self.mass * self.radius**2)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        """Free flight: `x'' = 0`, `z'' = -gravity`, `angle'' = torque / I`."""
        del t
        zero = jnp.zeros_like(y[0])
        return jnp.stack([y[3], y[4], y[5], zero, zero - self.gravity, u[0] / self.inertia + zero])

    def energy(self, y: State) -> Scalar:
        """Kinetic (translation and spin) plus gravitational potential energy."""
        return 0.5 * self.mass * (y[3] ** 2 + y[4] ** 2) + 0.5 * self.inertia * y[5] ** 2 + self.mass * self.gravity * y[1]


@final
class DiskFloor(AbstractParametrised):
    """The floor under a `RollingDiskDynamics`: Coulomb friction and Newton's restitution.

    `static_friction` (`mu_s`) and `kinetic_friction` (`mu_k <= mu_s`) act on the contact
    point's slip; `restitution` `e` on the normal velocity at an impact, whose tangential
    impulse is the smaller in magnitude of what stops the slip and `mu_k J_n` (Coulomb at
    the impact: a sticking or a sliding impact). A rebound slower than `min_rebound_speed`
    (m/s) closes the contact. `max_events` (static) bounds the located events of one step.
    """

    static_friction: Scalar = eqx.field(default=0.6, converter=NONNEGATIVE)
    kinetic_friction: Scalar = eqx.field(default=0.4, converter=NONNEGATIVE)
    restitution: Scalar = eqx.field(default=0.5, converter=RESTITUTION)
    min_rebound_speed: Scalar = eqx.field(default=0.05, converter=POSITIVE)
    max_events: int = option(16, None)

    def __check_init__(self):
        check_coulomb(self)

    def impact(self, dynamics: RollingDiskDynamics, y: State) -> State:
        """The state just after an impact of the disk at `y` (touching, `z_dot < 0`) on the floor.

        Normal impulse `J_n = (1 + e) m |z_dot|`; the tangential impulse `J_t` that would stop
        the slip is `-m_eff w` with `1 / m_eff = 1 / m + r^2 / I`, applied if `|J_t| <=
        mu_k J_n` (a sticking impact: the slip is then set to exactly zero), else
        `-mu_k J_n sign(w)` (a sliding impact).
        """
        mass, radius, inertia = dynamics.mass, dynamics.radius, dynamics.inertia
        slip = dynamics.slip_velocity(y)
        normal_impulse = (1 + self.restitution) * mass * jnp.maximum(-y[4], 0.0)
        effective_mass = 1 / (1 / mass + radius**2 / inertia)
        stopping = -effective_mass * slip
        limit = self.kinetic_friction * normal_impulse
        sticks = jnp.abs(stopping) <= limit
        tangential = jnp.where(sticks, stopping, -limit * jnp.sign(slip))
        angle_rate = y[5] - radius * tangential / inertia
        x_rate = jnp.where(sticks, radius * angle_rate, y[3] + tangential / mass)
        return y.at[3].set(x_rate).at[4].set(-self.restitution * y[4]).at[5].set(angle_rate)


__all__ = ["DiskFloor", "RollingDiskDynamics"]
