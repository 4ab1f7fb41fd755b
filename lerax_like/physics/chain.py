"""Articulated chains of uniform rods: an n-link pendulum and n poles on a cart.

One mechanism serves both. The rods are uniform and thin: rod `i` has mass `m_i`, full
length `l_i`, its centre of mass at half length and moment of inertia `m_i l_i**2 / 12`
about it. Angles are absolute and measured from upright, positive towards `+x`, as in
`CartPoleDynamics`: rod `i` runs from `p_{i-1}` to `p_i = p_{i-1} + l_i (sin theta_i,
cos theta_i)`, and `p_0` is the fixed pivot or the hinge on the cart at `(x, 0)`.

With generalised coordinates `q = [x, theta_1, ..., theta_n]` (no `x` without a cart) the
Euler-Lagrange equations read `M(q) q'' = Q - C(q, q') - G(q)`. Writing

- `b_i = l_i (m_i / 2 + sum_{k > i} m_k)` (first moment of the rods hanging from joint i),
- `A_ii = l_i**2 (m_i / 3 + sum_{k > i} m_k)` and `A_ij = l_i l_j (m_j / 2 + sum_{k > j} m_k)`
  for `i < j` (symmetric),

the kinetic energy is `T = 1/2 q'^T M q'` with `M_thth[i, j] = A_ij cos(theta_i - theta_j)`,
`M_xth[i] = b_i cos theta_i`, `M_xx = cart_mass + sum_k m_k`; the potential energy is
`V = g sum_i b_i cos theta_i`; the bias forces are
`C_theta_i = sum_j A_ij sin(theta_i - theta_j) theta_j'**2`, `C_x = -sum_i b_i sin theta_i theta_i'**2`,
`G_theta_i = -g b_i sin theta_i`, `G_x = 0`. The number of rods is static (array shapes);
masses and lengths are differentiable leaves.
"""

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import POSITIVE
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractChainDynamics


# A per-link parameter: one positive entry per link, as many as every other per-link one.
PER_LINK = POSITIVE.shaped("n")


def _moments(masses: Float[Array, " n"], lengths: Float[Array, " n"]):
    """`b` (n,) and `A` (n, n) of the module docstring."""
    # Mass of the rods strictly beyond rod i: sum_{k > i} m_k.
    beyond = jnp.cumsum(masses[::-1])[::-1] - masses
    first_moment = lengths * (masses / 2 + beyond)
    n = masses.shape[0]
    index = np.arange(n)
    later = np.maximum(index[:, None], index[None, :])
    coupling = lengths[:, None] * lengths[None, :] * (masses / 2 + beyond)[later]
    diagonal = lengths**2 * (masses / 3 + beyond)
    coupling = jnp.where(index[:, None] == index[None, :], diagonal[:, None], coupling)
    return first_moment, coupling


def chain_mass_matrix(
    masses: Float[Array, " n"],
    lengths: Float[Array, " n"],
    angles: Float[Array, " n"],
    cart_mass: Scalar | None = None,
) -> Float[Array, "q q"]:
    """The mass matrix `M(q)`; `q = [x, angles]` with a cart, `q = angles` without."""
    first_moment, coupling = _moments(masses, lengths)
    angular = coupling * jnp.cos(angles[:, None] - angles[None, :])
    if cart_mass is None:
        return angular
    cross = first_moment * jnp.cos(angles)
    top = jnp.concatenate([(cart_mass + jnp.sum(masses))[None], cross])
    return jnp.concatenate([top[None, :], jnp.concatenate([cross[:, None], angular], axis=1)], axis=0)


def chain_bias_forces(
    masses: Float[Array, " n"],
    lengths: Float[Array, " n"],
    gravity: Scalar,
    angles: Float[Array, " n"],
    angular_velocities: Float[Array, " n"],
    cart: bool = False,
) -> Float[Array, " q"]:
    """Coriolis, centrifugal and gravity forces `C(q, q') + G(q)` (cart row first if `cart`)."""
    first_moment, coupling = _moments(masses, lengths)
    sin_difference = jnp.sin(angles[:, None] - angles[None, :])
    centrifugal = (coupling * sin_difference) @ angular_velocities**2
    gravitational = -gravity * first_moment * jnp.sin(angles)
    bias = centrifugal + gravitational
    if not cart:
        return bias
    cart_bias = -jnp.sum(first_moment * jnp.sin(angles) * angular_velocities**2)
    return jnp.concatenate([cart_bias[None], bias])


def chain_potential_energy(
    masses: Float[Array, " n"], lengths: Float[Array, " n"], gravity: Scalar, angles: Float[Array, " n"]
) -> Scalar:
    """Gravitational potential energy, zero with every centre of mass at the pivot's height."""
    first_moment, _ = _moments(masses, lengths)
    return gravity * jnp.sum(first_moment * jnp.cos(angles))


def _lagrange_derivative(dynamics, y: State, forces: Float[Array, " q"]) -> State:
    """`[q_dot, q'']` with `M(q) q'' = forces - C(q, q') - G(q)`: both chains' vector field."""
    _, velocities = dynamics.coordinates(y)
    accelerations = jnp.linalg.solve(dynamics.mass_matrix(y), forces - dynamics.bias_forces(y))
    return jnp.concatenate([velocities, accelerations])


@final
class NLinkPendulumDynamics(AbstractChainDynamics):
    """n uniform rods in a chain from a fixed pivot, with a torque at every joint.

    State `y = [theta_1, ..., theta_n, theta_1_dot, ..., theta_n_dot]`, angles absolute
    from upright. Input `u` of shape `(n,)`: `u_i` is the torque that rod `i - 1` (the
    ground for `i = 1`) exerts on rod `i`; rod `i - 1` feels `-u_i`. The generalised force
    on `theta_i` is therefore `u_i - u_{i+1}`.
    """

    velocity_indices: ClassVar[None] = None  # the layout depends on the number of links
    has_cart: ClassVar[bool] = False

    masses: Float[Array, " n"] = eqx.field(default=(1.0, 1.0, 1.0), converter=PER_LINK)
    lengths: Float[Array, " n"] = eqx.field(default=(1.0, 1.0, 1.0), converter=PER_LINK)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    @property
    def n_links(self) -> int:
        return self.masses.shape[0]

    def mass_matrix(self, y: State) -> Float[Array, "n n"]:
        return chain_mass_matrix(self.masses, self.lengths, y[: self.n_links])

    def generalised_forces(self, u: Input) -> Float[Array, " n"]:
        return u - jnp.concatenate([u[1:], jnp.zeros_like(u[:1])])

    def coordinates(self, y: State) -> tuple[Float[Array, " n"], Float[Array, " n"]]:
        return y[: self.n_links], y[self.n_links :]

    def bias_forces(self, y: State) -> Float[Array, " n"]:
        return chain_bias_forces(self.masses, self.lengths, self.gravity, *self.coordinates(y))

    def forced_vector_field(
        self, t: ScalarLike, y: State, u: Input, generalised_force: Float[Array, " n"]
    ) -> State:
        del t
        return _lagrange_derivative(self, y, self.generalised_forces(u) + generalised_force)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        return self.forced_vector_field(t, y, u, jnp.zeros((self.n_links,), dtype=y.dtype))

    def energy(self, y: State) -> Scalar:
        n = self.n_links
        kinetic = 0.5 * y[n:] @ self.mass_matrix(y) @ y[n:]
        return kinetic + self.potential_energy(y)

    def potential_energy(self, y: State) -> Scalar:
        """The links' gravitational potential energy, the part of `energy` without velocities."""
        return chain_potential_energy(self.masses, self.lengths, self.gravity, y[: self.n_links])


@final
class CartChainDynamics(AbstractChainDynamics):
    """A cart on a frictionless rail with a chain of n uniform poles hinged on it.

    One pole is the classic cart-pole (`CartPoleDynamics` with `half_length = length / 2`,
    in another state order); two poles make the double cart-pole.

    State `y = [x, theta_1, ..., theta_n, x_dot, theta_1_dot, ..., theta_n_dot]`, angles
    absolute from upright, positive towards `+x`. Input `u` of shape `(1,)`: the
    horizontal force on the cart. The joints are passive.
    """

    velocity_indices: ClassVar[None] = None  # the layout depends on the number of links
    has_cart: ClassVar[bool] = True

    cart_mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    pole_masses: Float[Array, " n"] = eqx.field(default=(0.1, 0.1), converter=PER_LINK)
    pole_lengths: Float[Array, " n"] = eqx.field(default=(1.0, 1.0), converter=PER_LINK)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    @property
    def n_links(self) -> int:
        return self.pole_masses.shape[0]

    def mass_matrix(self, y: State) -> Float[Array, "q q"]:
        return chain_mass_matrix(self.pole_masses, self.pole_lengths, y[1 : 1 + self.n_links], self.cart_mass)

    def coordinates(self, y: State) -> tuple[Float[Array, " q"], Float[Array, " q"]]:
        return y[: 1 + self.n_links], y[1 + self.n_links :]

    def bias_forces(self, y: State) -> Float[Array, " q"]:
        positions, velocities = self.coordinates(y)
        return chain_bias_forces(
            self.pole_masses, self.pole_lengths, self.gravity, positions[1:], velocities[1:], cart=True
        )

    def forced_vector_field(
        self, t: ScalarLike, y: State, u: Input, generalised_force: Float[Array, " q"]
    ) -> State:
        del t
        return _lagrange_derivative(self, y, generalised_force.at[0].add(u[0]))

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        return self.forced_vector_field(t, y, u, jnp.zeros((1 + self.n_links,), dtype=y.dtype))

    def energy(self, y: State) -> Scalar:
        n = self.n_links
        velocities = y[1 + n :]
        kinetic = 0.5 * velocities @ self.mass_matrix(y) @ velocities
        return kinetic + self.potential_energy(y)

    def potential_energy(self, y: State) -> Scalar:
        """The poles' gravitational potential energy, the part of `energy` without velocities."""
        return chain_potential_energy(self.pole_masses, self.pole_lengths, self.gravity, y[1 : 1 + self.n_links])

    def momentum(self, y: State) -> Scalar:
        """Horizontal momentum of cart and poles; conserved when the force is zero."""
        n = self.n_links
        return self.mass_matrix(y)[0] @ y[1 + n :]
