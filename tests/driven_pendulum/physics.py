"""A damped pendulum driven by a periodic torque (Baker and Gollub, "Chaotic Dynamics", 1996)."""

from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp

from lerax_like import FINITE, NONNEGATIVE, POSITIVE, AbstractDynamics


@final
class DrivenPendulumDynamics(AbstractDynamics):
    """`theta'' = -omega0^2 sin(theta) - damping theta' + drive_amplitude cos(drive_frequency t) + u[0]`.

    `theta` from the downward vertical; `u[0]` an extra torque per unit moment of inertia.
    State `y = [theta, theta_dot]`. Non-autonomous: `t` is the episode's time, so the drive
    runs on over the episode's steps.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    natural_frequency: jax.Array = eqx.field(default=1.0, converter=POSITIVE)
    damping: jax.Array = eqx.field(default=0.5, converter=NONNEGATIVE)
    drive_amplitude: jax.Array = eqx.field(default=1.15, converter=FINITE)
    drive_frequency: jax.Array = eqx.field(default=2.0 / 3.0, converter=NONNEGATIVE)

    def vector_field(self, t, y: jax.Array, u: jax.Array) -> jax.Array:
        theta, theta_dot = y
        drive = self.drive_amplitude * jnp.cos(self.drive_frequency * t)
        theta_acc = -self.natural_frequency**2 * jnp.sin(theta) - self.damping * theta_dot + drive + u[0]
        return jnp.stack([theta_dot, theta_acc])
