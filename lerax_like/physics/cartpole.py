from typing import ClassVar

import jax.numpy as jnp

from .._checks import as_parameter, check_nonnegative, check_positive, check_positive_or_inf
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


class CartPoleDynamics(AbstractConservativeDynamics):
    """A cart on a frictionless rail with a uniform pole hinged on it.

    The equations are those of Barto, Sutton and Anderson (1983) as used by Gymnasium's
    CartPole: a pole of mass `pole_mass` and half length `half_length` (moment of
    inertia `pole_mass * half_length**2 / 3` about its centre), a cart of mass
    `cart_mass`, and a horizontal force `u[0]` on the cart.

    State `y = [x, x_dot, theta, theta_dot]` (Gymnasium's order), with `theta` measured
    from upright, positive towards `+x`.

    Two stiff effects that real rigs have, both off (0) by default, which keeps
    Gymnasium's equations exactly:

    - `joint_damping` `b` (N m s/rad): viscous friction in the hinge, a torque
      `-b theta_dot` on the pole (the joint only rotates, so it does no work on `x`). With
      the default masses, `b = 300` gives an eigenvalue of about `-1e4`.
    - End stops at `x = -track_limit` and `x = +track_limit`: a one-sided spring-damper
      (`end_stop_stiffness` `k` in N/m, up to 1e6, `end_stop_damping` `c` in N s/m) pushes
      the cart back with `max(k p + c p', 0)` where `p >= 0` is the penetration; it never
      pulls. This is a contact: the vector field is continuous in `x` but only piecewise
      smooth, and with `c > 0` it jumps in `x_dot` at the moment of contact.

    Both enter Lagrange's equations as generalised forces, `Q_x = u + F_stop` and
    `Q_theta = -b theta_dot`; `tests/test_stiff.py` rederives the accelerations with SymPy.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1, 3)

    gravity: Scalar
    cart_mass: Scalar
    pole_mass: Scalar
    half_length: Scalar
    joint_damping: Scalar
    end_stop_stiffness: Scalar
    end_stop_damping: Scalar
    track_limit: Scalar

    def __init__(
        self,
        gravity: ScalarLike = 9.8,
        cart_mass: ScalarLike = 1.0,
        pole_mass: ScalarLike = 0.1,
        half_length: ScalarLike = 0.5,
        joint_damping: ScalarLike = 0.0,
        end_stop_stiffness: ScalarLike = 0.0,
        end_stop_damping: ScalarLike = 0.0,
        track_limit: ScalarLike = 2.4,
    ):
        for name, value in [
            ("gravity", gravity),
            ("cart_mass", cart_mass),
            ("pole_mass", pole_mass),
            ("half_length", half_length),
        ]:
            check_positive(value, name)
        for name, value in [
            ("joint_damping", joint_damping),
            ("end_stop_stiffness", end_stop_stiffness),
            ("end_stop_damping", end_stop_damping),
        ]:
            check_nonnegative(value, name)
        check_positive_or_inf(track_limit, "track_limit")
        self.gravity = as_parameter(gravity, "gravity")
        self.cart_mass = as_parameter(cart_mass, "cart_mass")
        self.pole_mass = as_parameter(pole_mass, "pole_mass")
        self.half_length = as_parameter(half_length, "half_length")
        self.joint_damping = as_parameter(joint_damping, "joint_damping")
        self.end_stop_stiffness = as_parameter(end_stop_stiffness, "end_stop_stiffness")
        self.end_stop_damping = as_parameter(end_stop_damping, "end_stop_damping")
        self.track_limit = as_parameter(track_limit, "track_limit")

    @property
    def total_mass(self) -> Scalar:
        return self.cart_mass + self.pole_mass

    def _penetrations(self, x: Scalar) -> tuple[Scalar, Scalar]:
        """How far the cart is past the left and the right end stop (>= 0)."""
        return jnp.maximum(-self.track_limit - x, 0.0), jnp.maximum(x - self.track_limit, 0.0)

    def end_stop_force(self, x: Scalar, x_dot: Scalar) -> Scalar:
        """The horizontal force of the end stops on the cart (zero off contact)."""
        left, right = self._penetrations(x)
        # One-sided: a damper that would pull the cart back into the stop as it leaves
        # is clipped to zero, as a real bumper cannot pull.
        push_left = jnp.where(left > 0, self.end_stop_stiffness * left - self.end_stop_damping * x_dot, 0.0)
        push_right = jnp.where(right > 0, self.end_stop_stiffness * right + self.end_stop_damping * x_dot, 0.0)
        return jnp.maximum(push_left, 0.0) - jnp.maximum(push_right, 0.0)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        x, x_dot, theta, theta_dot = y
        # With the stiff options off both additions are exact zeros, so the arithmetic
        # below is Gymnasium's to the bit.
        force = u[0] + self.end_stop_force(x, x_dot)
        sin_theta = jnp.sin(theta)
        cos_theta = jnp.cos(theta)
        total_mass = self.total_mass
        pole_mass_length = self.pole_mass * self.half_length
        # Written in Gymnasium's order of operations so that one Euler step agrees with
        # it to the last few ulps in float64.
        temp = (force + pole_mass_length * theta_dot**2 * sin_theta) / total_mass
        damping = self.joint_damping * theta_dot / pole_mass_length
        theta_acc = (self.gravity * sin_theta - cos_theta * temp - damping) / (
            self.half_length * (4.0 / 3.0 - self.pole_mass * cos_theta**2 / total_mass)
        )
        x_acc = temp - pole_mass_length * theta_acc * cos_theta / total_mass
        return jnp.stack([x_dot, x_acc, theta_dot, theta_acc])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus potential energy, the end stops' springs included.

        Conserved when the input, `joint_damping` and `end_stop_damping` are zero.
        """
        x, x_dot, theta, theta_dot = y
        m, l = self.pole_mass, self.half_length
        kinetic = (
            0.5 * self.total_mass * x_dot**2
            + m * l * jnp.cos(theta) * x_dot * theta_dot
            + (2.0 / 3.0) * m * l**2 * theta_dot**2
        )
        left, right = self._penetrations(x)
        springs = 0.5 * self.end_stop_stiffness * (left**2 + right**2)
        return kinetic + m * self.gravity * l * jnp.cos(theta) + springs

    def momentum(self, y: State) -> Scalar:
        """Horizontal momentum of cart and pole; conserved when the force is zero and the
        cart is off the end stops."""
        _, x_dot, theta, theta_dot = y
        return self.total_mass * x_dot + self.pole_mass * self.half_length * jnp.cos(theta) * theta_dot
