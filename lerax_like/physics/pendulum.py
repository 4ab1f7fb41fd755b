from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


@final
class PendulumDynamics(AbstractConservativeDynamics):
    """A uniform rod of mass `mass` and length `length` on a frictionless pivot at one end.

    Gymnasium's Pendulum-v1 physics: moment of inertia `mass * length**2 / 3` about the
    pivot, gravity `gravity` acting at the rod's centre, a torque `u[0]` at the pivot.

    State `y = [theta, theta_dot]`, `theta` measured from upright, counter-clockwise.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    gravity: Scalar = eqx.field(default=10.0, converter=POSITIVE)  # m/s^2
    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg
    length: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # m

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        theta, theta_dot = y
        g, m, l = self.gravity, self.mass, self.length
        # Gymnasium's order of operations, so that a semi-implicit step agrees to the ulp.
        theta_acc = 3 * g / (2 * l) * jnp.sin(theta) + 3.0 / (m * l**2) * u[0]
        return jnp.stack([theta_dot, theta_acc])

    def energy(self, y: State) -> Scalar:
        theta, theta_dot = y
        m, l = self.mass, self.length
        return m * l**2 / 6 * theta_dot**2 + m * self.gravity * l / 2 * jnp.cos(theta)
