from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractChainDynamics


@final
class CartPoleDynamics(AbstractChainDynamics):
    """A cart on a frictionless rail with a uniform pole hinged on it.

    The equations are those of Barto, Sutton and Anderson (1983) as used by Gymnasium's
    CartPole: a pole of mass `pole_mass` and half length `half_length` (moment of
    inertia `pole_mass * half_length**2 / 3` about its centre), a cart of mass
    `cart_mass`, and a horizontal force `u[0]` on the cart.

    State `y = [x, x_dot, theta, theta_dot]` (Gymnasium's order), with `theta` measured
    from upright, positive towards `+x`; generalised coordinates `q = [x, theta]`.

    Hinge friction and end stops are not part of it: they are add-ons
    (`lerax_like.physics.forces.JointDamping`, `EndStops`) composed with
    `ForcedDynamics`, so that the plain cart-pole holds and computes only Gymnasium's
    four parameters and equations.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1, 3)
    has_cart: ClassVar[bool] = True

    gravity: Scalar = eqx.field(default=9.8, converter=POSITIVE)  # m/s^2
    cart_mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg
    pole_mass: Scalar = eqx.field(default=0.1, converter=POSITIVE)  # kg
    half_length: Scalar = eqx.field(default=0.5, converter=POSITIVE)  # m, pivot to the pole's centre

    @property
    def total_mass(self) -> Scalar:
        return self.cart_mass + self.pole_mass

    def _derivative(self, y: State, force: Scalar, torque: Scalar | None) -> State:
        # Written in Gymnasium's order of operations so that one Euler step agrees with
        # it to the last few ulps in float64. `torque` (on the pole, from the cart) is
        # None for the plain field, which then has no term for it at all.
        x, x_dot, theta, theta_dot = y
        del x
        sin_theta = jnp.sin(theta)
        cos_theta = jnp.cos(theta)
        total_mass = self.total_mass
        pole_mass_length = self.pole_mass * self.half_length
        temp = (force + pole_mass_length * theta_dot**2 * sin_theta) / total_mass
        numerator = self.gravity * sin_theta - cos_theta * temp
        if torque is not None:
            numerator = numerator + torque / pole_mass_length
        theta_acc = numerator / (self.half_length * (4.0 / 3.0 - self.pole_mass * cos_theta**2 / total_mass))
        x_acc = temp - pole_mass_length * theta_acc * cos_theta / total_mass
        return jnp.stack([x_dot, x_acc, theta_dot, theta_acc])

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        return self._derivative(y, u[0], None)

    def coordinates(self, y: State) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
        return y[::2], y[1::2]

    def forced_vector_field(self, t: ScalarLike, y: State, u: Input, generalised_force: Float[Array, " 2"]) -> State:
        # A force on x adds to the cart's force; a torque on theta enters the pole's
        # equation as the pole's own weight torque does, over m l.
        del t
        return self._derivative(y, u[0] + generalised_force[0], generalised_force[1])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus gravitational potential energy; conserved when the input is zero."""
        x, x_dot, theta, theta_dot = y
        m, l = self.pole_mass, self.half_length
        kinetic = (
            0.5 * self.total_mass * x_dot**2
            + m * l * jnp.cos(theta) * x_dot * theta_dot
            + (2.0 / 3.0) * m * l**2 * theta_dot**2
        )
        return kinetic + self.potential_energy(y)

    def potential_energy(self, y: State) -> Scalar:
        """The pole's gravitational potential energy, the part of `energy` without velocities."""
        return self.pole_mass * self.gravity * self.half_length * jnp.cos(y[2])

    def mass_matrix(self, y: State) -> Float[Array, "2 2"]:
        """`M(q)`, the Hessian of `energy` in `(x_dot, theta_dot)`, in closed form."""
        off_diagonal = self.pole_mass * self.half_length * jnp.cos(y[2])
        return jnp.stack([
            jnp.stack([self.total_mass, off_diagonal]),
            jnp.stack([off_diagonal, (4.0 / 3.0) * self.pole_mass * self.half_length**2]),
        ])

    def momentum(self, y: State) -> Scalar:
        """Horizontal momentum of cart and pole; conserved when the force is zero."""
        _, x_dot, theta, theta_dot = y
        return self.total_mass * x_dot + self.pole_mass * self.half_length * jnp.cos(theta) * theta_dot
