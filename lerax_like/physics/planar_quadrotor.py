"""A quadrotor in the vertical plane: a rigid body with two rotors at the ends of its arm."""

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


@final
class PlanarQuadrotorDynamics(AbstractConservativeDynamics):
    """A planar quadrotor: a rigid body of `mass` and `moment_of_inertia` about its centre,
    with two rotors at `arm_length` either side of the centre, each thrusting along the
    body's up axis.

    State `y = [x, z, theta, x_dot, z_dot, theta_dot]`: position (m, `z` up), attitude
    `theta` (rad, counter-clockwise from level) and their rates. Input
    `u = [left thrust, right thrust]` (N). With `T = u0 + u1`:

        x'' = -T sin(theta) / mass
        z'' =  T cos(theta) / mass - gravity
        theta'' = arm_length (u1 - u0) / moment_of_inertia

    Unpowered it falls freely and spins at a constant rate: `energy` is conserved.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (3, 4, 5)

    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    arm_length: Scalar = eqx.field(default=0.25, converter=POSITIVE)
    moment_of_inertia: Scalar = eqx.field(default=0.01, converter=POSITIVE)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        theta, velocities = y[2], y[3:]
        thrust = u[0] + u[1]
        x_acc = -thrust * jnp.sin(theta) / self.mass
        z_acc = thrust * jnp.cos(theta) / self.mass - self.gravity
        theta_acc = self.arm_length * (u[1] - u[0]) / self.moment_of_inertia
        return jnp.concatenate([velocities, jnp.stack([x_acc, z_acc, theta_acc])])

    def energy(self, y: State) -> Scalar:
        z, x_dot, z_dot, theta_dot = y[1], y[3], y[4], y[5]
        kinetic = 0.5 * self.mass * (x_dot**2 + z_dot**2) + 0.5 * self.moment_of_inertia * theta_dot**2
        return kinetic + self.mass * self.gravity * z
