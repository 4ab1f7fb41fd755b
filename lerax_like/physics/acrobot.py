from typing import ClassVar, Literal, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE, option
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


@final
class AcrobotDynamics(AbstractConservativeDynamics):
    """Two links in a vertical plane, hinged in series, with a torque `u[0]` at the elbow only.

    The equations are those of Sutton and Barto's book (and of Gymnasium's Acrobot-v1 with
    `book_or_nips="book"`): link `i` has mass `link_mass_i`, centre of mass at
    `link_com_position_i` from its hinge and moment of inertia `link_moment_of_inertia_i`
    about that centre; link 1 has length `link_length_1` (link 2's length does not enter
    the dynamics). `equations="nips"` gives the variant of the 1995 NeurIPS paper, which
    drops a Coriolis term and so conserves no energy.

    State `y = [theta_1, theta_2, theta_1_dot, theta_2_dot]`: `theta_1` is link 1's angle
    from hanging straight down, `theta_2` link 2's angle relative to link 1.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (2, 3)

    gravity: Scalar = eqx.field(default=9.8, converter=POSITIVE)  # m/s^2
    link_length_1: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # m
    link_mass_1: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg
    link_mass_2: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg
    link_com_position_1: Scalar = eqx.field(default=0.5, converter=POSITIVE)  # m from the shoulder
    link_com_position_2: Scalar = eqx.field(default=0.5, converter=POSITIVE)  # m from the elbow
    link_moment_of_inertia_1: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg m^2
    link_moment_of_inertia_2: Scalar = eqx.field(default=1.0, converter=POSITIVE)  # kg m^2
    equations: Literal["book", "nips"] = option("book", ("book", "nips"))

    @property
    def conserves_energy(self) -> bool:
        # The NeurIPS variant drops a Coriolis term: its `energy` is not conserved.
        return self.equations == "book"

    def _mass_matrix(self, theta_2: Scalar) -> tuple[Scalar, Scalar, Scalar]:
        m1, m2 = self.link_mass_1, self.link_mass_2
        l1, lc1, lc2 = self.link_length_1, self.link_com_position_1, self.link_com_position_2
        i1, i2 = self.link_moment_of_inertia_1, self.link_moment_of_inertia_2
        d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * jnp.cos(theta_2)) + i1 + i2
        d2 = m2 * (lc2**2 + l1 * lc2 * jnp.cos(theta_2)) + i2
        return d1, d2, m2 * lc2**2 + i2

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        theta_1, theta_2, dtheta_1, dtheta_2 = y
        m1, m2 = self.link_mass_1, self.link_mass_2
        l1, lc1, lc2 = self.link_length_1, self.link_com_position_1, self.link_com_position_2
        g = self.gravity
        torque = u[0]
        d1, d2, d22 = self._mass_matrix(theta_2)
        # Gymnasium's `_dsdt`, term for term, so that one RK4 step agrees to the ulp.
        phi2 = m2 * lc2 * g * jnp.cos(theta_1 + theta_2 - jnp.pi / 2.0)
        phi1 = (
            -m2 * l1 * lc2 * dtheta_2**2 * jnp.sin(theta_2)
            - 2 * m2 * l1 * lc2 * dtheta_2 * dtheta_1 * jnp.sin(theta_2)
            + (m1 * lc1 + m2 * l1) * g * jnp.cos(theta_1 - jnp.pi / 2)
            + phi2
        )
        if self.equations == "nips":
            ddtheta_2 = (torque + d2 / d1 * phi1 - phi2) / (d22 - d2**2 / d1)
        else:
            ddtheta_2 = (
                torque + d2 / d1 * phi1 - m2 * l1 * lc2 * dtheta_1**2 * jnp.sin(theta_2) - phi2
            ) / (d22 - d2**2 / d1)
        ddtheta_1 = -(d2 * ddtheta_2 + phi1) / d1
        return jnp.stack([dtheta_1, dtheta_2, ddtheta_1, ddtheta_2])

    def energy(self, y: State) -> Scalar:
        theta_1, theta_2, dtheta_1, dtheta_2 = y
        d1, d2, d22 = self._mass_matrix(theta_2)
        kinetic = 0.5 * d1 * dtheta_1**2 + d2 * dtheta_1 * dtheta_2 + 0.5 * d22 * dtheta_2**2
        potential = -self.gravity * (
            (self.link_mass_1 * self.link_com_position_1 + self.link_mass_2 * self.link_length_1)
            * jnp.cos(theta_1)
            + self.link_mass_2 * self.link_com_position_2 * jnp.cos(theta_1 + theta_2)
        )
        return kinetic + potential
