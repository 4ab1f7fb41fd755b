"""The simplest walking model (Garcia, Chatterjee, Ruina and Coleman, 1998)."""

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._types import Input, Scalar, ScalarLike, State
from .walker import SLOPE, AbstractWalkerDynamics, swing_gap


@final
class SimplestWalkerDynamics(AbstractWalkerDynamics):
    """The simplest walker: a point mass at the hip, rigid massless legs, point feet of vanishing mass.

    M. Garcia, A. Chatterjee, A. Ruina and M. Coleman, "The simplest walking model:
    stability, complexity, and scaling", ASME J. Biomech. Eng. 120 (1998) 281-288, in the
    limit of the paper's foot-to-hip mass ratio `beta -> 0`, nondimensional (time in units
    of `sqrt(l / g)`, torque of `M g l`): the slope `slope` (gamma, radians) is the only
    parameter. State `y = [theta, phi, theta_dot, phi_dot]`, the paper's: `theta` the
    stance leg's angle from the slope's normal (positive uphill, the hip behind the foot),
    `phi` the angle from the stance leg to the swing leg. In stance (eq. 3 of the paper),

        theta'' = sin(theta - gamma) - u
        phi''   = (1 - cos phi) theta'' + theta_dot**2 sin phi + sin(theta - phi - gamma)

    which with `u = 0` is the paper's `phi'' = sin(theta - gamma) + sin phi (theta_dot**2 -
    cos(theta - gamma))`; `u[0]` is an ankle torque at the stance foot, positive downhill (the
    swing leg, hanging from the hip, feels it through the hip's acceleration).

    The heel strike is `phi - 2 theta = 0` with the stance leg past the normal (`front_gap`,
    which ignores the swing foot's scuffing at mid-stance as the paper does); its map, the
    legs' exchange with the angular momentum of the hip about the new foot conserved
    (eq. 4): `theta+ = -theta-`, `phi+ = -phi-`, `theta_dot+ = cos(2 theta) theta_dot-`,
    `phi_dot+ = cos(2 theta) (1 - cos(2 theta)) theta_dot-`.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (2, 3)
    # The state's components by name, as the docstring writes them (`lerax-like gait` prints them).
    state_names: ClassVar[tuple[str, ...]] = ("theta", "phi", "theta_dot", "phi_dot")

    slope: Scalar = eqx.field(default=0.009, converter=SLOPE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        theta, phi, theta_dot, phi_dot = y
        gamma = self.slope
        theta_acc = jnp.sin(theta - gamma) - u[0]
        phi_acc = (1 - jnp.cos(phi)) * theta_acc + theta_dot**2 * jnp.sin(phi) + jnp.sin(theta - phi - gamma)
        return jnp.stack([theta_dot, phi_dot, theta_acc, phi_acc])

    def energy(self, y: State) -> Scalar:
        """The hip's kinetic plus potential energy (the feet have no mass), conserved in stance with `u = 0`."""
        theta, _, theta_dot, _ = y
        return theta_dot**2 / 2 + jnp.cos(theta - self.slope)

    def front_gap(self, y: State) -> Scalar:
        theta, phi, theta_dot, phi_dot = y
        return swing_gap(theta, 2 * theta - phi, 2 * theta_dot - phi_dot)

    def heel_strike(self, y: State) -> State:
        theta, phi, theta_dot, _ = y
        c = jnp.cos(2 * theta)
        return jnp.stack([-theta, -phi, c * theta_dot, c * (1 - c) * theta_dot])

    def stance_angle(self, y: State) -> Scalar:
        return -y[0]

    def hip_speed(self, y: State) -> Scalar:
        """In units of `sqrt(g l)`: the hip at `-sin(theta)` along the slope from the stance foot."""
        return -jnp.cos(y[0]) * y[2]

    def on_section(self, theta: ScalarLike, theta_dot: ScalarLike) -> State:
        """The state just after a heel strike with stance angle `theta` and rate `theta_dot`."""
        theta, theta_dot = jnp.asarray(theta), jnp.asarray(theta_dot)
        return jnp.stack([theta, 2 * theta, theta_dot, (1 - jnp.cos(2 * theta)) * theta_dot])


__all__ = ["SimplestWalkerDynamics"]
