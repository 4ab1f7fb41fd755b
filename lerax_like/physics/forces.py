"""Optional physics as add-ons: generalised forces that compose with any cart or chain.

A physics module holds only its own parameters and equations (`CartPoleDynamics` is
Gymnasium's four). What a real rig adds on top, hinge friction or end stops on the rail,
is a generalised force `Q(y)` on the coordinates `q` of an `AbstractChainDynamics`, and
`ForcedDynamics(dynamics, forces)` adds their sum to Lagrange's equations,
`M(q) q'' = u + Q - C(q, q') - G(q)`, the way diffrax composes terms. A scene built
without add-ons carries none of this and computes none of it.

    rig = ForcedDynamics(
        CartPoleDynamics(), (JointDamping(joint_damping=1.0), EndStops(end_stop_stiffness=1e5))
    )

A scene holds its add-ons in a field (`CartPole(forces=(JointDamping(joint_damping=1.0),))`), and
`lerax_like.make` builds them from flat keywords (`make("CartPole", joint_damping=1.0)`).
"""

import abc
from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE, POSITIVE_OR_INF, AbstractParametrised
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractChainDynamics, AbstractConservativeDynamics, AbstractDynamics


class AbstractGeneralisedForce(AbstractParametrised):
    """A generalised force on the coordinates `q` of a cart or a chain.

    Subclasses declare `conservative` (whether the force conserves energy, its potential
    energy included) and `requires_cart` (whether it acts on the cart's coordinate `x`,
    so that dynamics without a cart are refused), declare their parameters as fields
    (`eqx.field(default=..., converter=RANGE)`: converted and checked by name), and implement
    `generalised_force` and `potential_energy`.
    """

    conservative: eqx.AbstractClassVar[bool]
    requires_cart: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def generalised_force(self, dynamics: AbstractChainDynamics, y: State) -> Float[Array, " q"]:
        """The force on the generalised coordinates `q` of `dynamics` in the state `y`."""

    @abc.abstractmethod
    def potential_energy(self, dynamics: AbstractChainDynamics, y: State) -> Scalar:
        """The potential energy of the force in the state `y` (0 for a force without one)."""

    def check(self, dynamics: AbstractDynamics) -> None:
        """Refuse, with a `ValueError` naming both, dynamics this add-on cannot act on."""
        name, target = type(self).__name__, type(dynamics).__name__
        if not isinstance(dynamics, AbstractChainDynamics):
            raise ValueError(
                f"{name} acts on the generalised coordinates of a cart or a chain "
                f"(an AbstractChainDynamics), not on {target}"
            )
        if self.requires_cart and not dynamics.has_cart:
            raise ValueError(f"{name} acts on a cart's position, and {target} has no cart")


@final
class JointDamping(AbstractGeneralisedForce):
    """Viscous friction in every hinge of a chain, `joint_damping` `b` in N m s/rad.

    Joint `i` joins link `i` to link `i - 1` (the cart, or the fixed ground for a chain
    without one, for `i = 1`, which does not rotate). Its damper acts on the relative
    rate: a torque `tau_i = -b (theta_i_dot - theta_{i-1}_dot)` on link `i` and `-tau_i`
    on link `i - 1`. On the absolute angles the generalised force is therefore
    `Q_theta_i = tau_i - tau_{i+1}` (no `tau_{n+1}`), and nothing on the cart's `x`: a
    torque does no work on a body that only translates. On a cart-pole it is the torque
    `-b theta_dot` on the pole. It only dissipates: the rate of change of energy is
    `-b sum_i (theta_i_dot - theta_{i-1}_dot)**2`.
    """

    conservative: ClassVar[bool] = False
    requires_cart: ClassVar[bool] = False

    joint_damping: Scalar = eqx.field(converter=NONNEGATIVE)

    def generalised_force(self, dynamics: AbstractChainDynamics, y: State) -> Float[Array, " q"]:
        _, rates = dynamics.coordinates(y)
        angular = rates[1:] if dynamics.has_cart else rates
        # The neighbour of joint 1 (cart or ground) has zero angular rate.
        relative = angular - jnp.concatenate([jnp.zeros_like(angular[:1]), angular[:-1]])
        torque = -self.joint_damping * relative
        on_angles = torque - jnp.concatenate([torque[1:], jnp.zeros_like(torque[:1])])
        if dynamics.has_cart:
            return jnp.concatenate([jnp.zeros_like(rates[:1]), on_angles])
        return on_angles

    def potential_energy(self, dynamics: AbstractChainDynamics, y: State) -> Scalar:
        del dynamics
        return jnp.zeros((), dtype=y.dtype)


@final
class EndStops(AbstractGeneralisedForce):
    """One-sided spring-dampers at the ends of a cart's rail, `x = -track_limit` and `+track_limit`.

    Past a stop by `p >= 0` (the penetration), the stop pushes the cart back with
    `max(k p + c p_dot, 0)`, `k = end_stop_stiffness` (N/m, up to 1e6), `c =
    end_stop_damping` (N s/m): it never pulls, as a real bumper cannot. This is a contact:
    the vector field is continuous in `x` but only piecewise smooth, and with `c > 0` it
    jumps in `x_dot` at the moment of contact (a stiff problem for `k` large: use an
    adaptive or implicit solver). The springs' potential energy is `k p**2 / 2`; energy
    is conserved when `c = 0`. `track_limit` may be `inf` (no stops).
    """

    conservative: ClassVar[bool] = False  # the damper dissipates unless end_stop_damping is 0
    requires_cart: ClassVar[bool] = True

    end_stop_stiffness: Scalar = eqx.field(default=0.0, converter=NONNEGATIVE)
    end_stop_damping: Scalar = eqx.field(default=0.0, converter=NONNEGATIVE)
    track_limit: Scalar = eqx.field(default=2.4, converter=POSITIVE_OR_INF)

    def _penetrations(self, x: Scalar) -> tuple[Scalar, Scalar]:
        """How far the cart is past the left and the right end stop (>= 0)."""
        return jnp.maximum(-self.track_limit - x, 0.0), jnp.maximum(x - self.track_limit, 0.0)

    def force(self, x: Scalar, x_dot: Scalar) -> Scalar:
        """The horizontal force of the end stops on the cart (zero off contact)."""
        left, right = self._penetrations(x)
        # One-sided: a damper that would pull the cart back into the stop as it leaves
        # is clipped to zero, as a real bumper cannot pull.
        push_left = jnp.where(left > 0, self.end_stop_stiffness * left - self.end_stop_damping * x_dot, 0.0)
        push_right = jnp.where(right > 0, self.end_stop_stiffness * right + self.end_stop_damping * x_dot, 0.0)
        return jnp.maximum(push_left, 0.0) - jnp.maximum(push_right, 0.0)

    def generalised_force(self, dynamics: AbstractChainDynamics, y: State) -> Float[Array, " q"]:
        positions, rates = dynamics.coordinates(y)
        return jnp.zeros_like(positions).at[0].set(self.force(positions[0], rates[0]))

    def potential_energy(self, dynamics: AbstractChainDynamics, y: State) -> Scalar:
        positions, _ = dynamics.coordinates(y)
        left, right = self._penetrations(positions[0])
        return 0.5 * self.end_stop_stiffness * (left**2 + right**2)


@final
class ForcedDynamics(AbstractConservativeDynamics):
    """A cart or a chain with generalised-force add-ons: `dynamics` plus the sum of `forces`.

    The vector field is `dynamics.forced_vector_field` with `Q = sum_f f.generalised_force`
    added to the input's generalised force; the energy is the dynamics' plus the
    add-ons' potential energies, conserved with zero input when `conserves_energy`
    (the dynamics conserve theirs and every add-on is conservative).
    Construction refuses an add-on that cannot act on `dynamics` (end stops without a
    cart, say), naming both.
    """

    dynamics: AbstractChainDynamics
    forces: tuple[AbstractGeneralisedForce, ...] = eqx.field(default=(), converter=tuple)

    def __check_init__(self):
        if not isinstance(self.dynamics, AbstractChainDynamics):
            raise ValueError(
                "ForcedDynamics adds generalised forces to a cart or a chain (an AbstractChainDynamics), "
                f"not to {type(self.dynamics).__name__}"
            )
        for force in self.forces:
            if not isinstance(force, AbstractGeneralisedForce):
                raise TypeError(
                    f"forces must be AbstractGeneralisedForce add-ons (JointDamping, EndStops, ...), got {force!r}"
                )
            force.check(self.dynamics)

    @property
    def velocity_indices(self) -> tuple[int, ...] | None:
        return self.dynamics.velocity_indices

    @property
    def conserves_energy(self) -> bool:
        """Whether `energy` is conserved with zero input: the dynamics' and every add-on's."""
        return self.dynamics.conserves_energy and all(force.conservative for force in self.forces)

    def generalised_force(self, y: State) -> Float[Array, " q"]:
        """The sum of the add-ons' generalised forces on the coordinates `q` of `dynamics`."""
        if not self.forces:
            return jnp.zeros_like(self.dynamics.coordinates(y)[0])
        total = self.forces[0].generalised_force(self.dynamics, y)
        for force in self.forces[1:]:
            total = total + force.generalised_force(self.dynamics, y)
        return total

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        if not self.forces:
            return self.dynamics.vector_field(t, y, u)
        return self.dynamics.forced_vector_field(t, y, u, self.generalised_force(y))

    def energy(self, y: State) -> Scalar:
        """The dynamics' energy plus the add-ons' potential energies."""
        total = self.dynamics.energy(y)
        for force in self.forces:
            total = total + force.potential_energy(self.dynamics, y)
        return total
