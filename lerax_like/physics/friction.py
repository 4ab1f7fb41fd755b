"""Coulomb friction as an add-on: stick and slip, each a mode, each switch a located event.

One sliding coordinate `q_k` (a cart on its rail, a block on its plane) with normal force
`N`, static coefficient `mu_s` and kinetic `mu_k <= mu_s`:

- slip in direction `s = +-1`: the friction force on `q_k` is `-mu_k |N| s`;
- stick: `q_k_dot = 0` held as a constraint, its force `f` whatever the dynamics need;
- slip -> stick when `q_k_dot` reaches zero and `|f| <= mu_s |N|` there (else the motion
  reverses through zero); stick -> slip when `|f|` reaches `mu_s |N|`.

`N` is read off the dynamics: it is affine in the accelerations (a cart carrying a
swinging pole presses on its rail by the pole's vertical reaction), so in slip the
friction force solves `f (1 + mu_k sigma s dN/df) = -mu_k sigma s N_0` with `sigma` the
sign of `N` (Florian's correction of Barto et al.: the normal force may change sign, and
the friction's `|N|` follows it). Where `1 + mu_k sigma s dN/df <= 0` no slip is
consistent (Painleve's paradox): the step reports it (`info["friction_consistent"]`)
and fails, never silently. The step that integrates the modes is `lerax_like.stick_slip`;
a scene built without friction holds and computes none of it.
"""

import abc
from typing import Any, ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._fields import NONNEGATIVE, AbstractParametrised, concrete, option
from .._types import Array, Float, Scalar, State
from ._base import AbstractDynamics, require_attributes
from .contact import mass_matrix, with_coordinates


def check_coulomb(owner) -> None:
    """Refuse, naming it, a `max_events` that is no positive integer, and a kinetic friction
    coefficient above the static one (`owner`'s `static_friction` and `kinetic_friction`)."""
    if isinstance(owner.max_events, bool) or not isinstance(owner.max_events, (int, np.integer)) or owner.max_events < 1:
        raise ValueError(f"max_events must be a positive integer, got {owner.max_events!r}")
    static, kinetic = concrete(owner.static_friction), concrete(owner.kinetic_friction)
    if static is not None and kinetic is not None and np.any(kinetic > static):
        raise ValueError(
            f"{type(owner).__name__}: the kinetic friction coefficient must not exceed the static one "
            f"(allowed range [0, static]), got kinetic {kinetic} > static {static}"
        )


class AbstractCoulombFriction(AbstractParametrised):
    """Dry friction on one generalised coordinate, `coordinate` (an index into `q`).

    Subclasses declare `static_friction` (`mu_s`) and `kinetic_friction` (`mu_k <= mu_s`)
    as parameters and implement `normal_force(dynamics, y, acceleration)`, affine in the
    accelerations `q''`. The dynamics must provide `coordinates(y) -> (q, q_dot)` and
    `forced_vector_field(t, y, u, Q)` (a generalised force `Q` on `q`), through which the
    friction force acts. `max_events` (static) bounds the switches located in one env step.
    """

    coordinate: ClassVar[int]
    static_friction: eqx.AbstractVar[Scalar]
    kinetic_friction: eqx.AbstractVar[Scalar]
    max_events: int = option(16, None)

    @abc.abstractmethod
    def normal_force(self, dynamics: AbstractDynamics, y: State, acceleration: Float[Array, " q"]) -> Scalar:
        """The normal force `N` in the state `y` when the coordinates accelerate by `acceleration`."""
        raise NotImplementedError

    @property
    def absent(self) -> bool:
        """Whether both coefficients are zero (concretely): a scene given its keywords so builds no friction."""
        static, kinetic = concrete(self.static_friction), concrete(self.kinetic_friction)
        return static is not None and kinetic is not None and not np.any(static) and not np.any(kinetic)

    def check(self, dynamics: AbstractDynamics) -> None:
        """Refuse, naming both, dynamics this friction cannot act on."""
        purpose = "generalised coordinates and a generalised force to act through"
        require_attributes(self, dynamics, ("coordinates", "forced_vector_field"), purpose)

    def __check_init__(self):
        check_coulomb(self)


@final
class CartFriction(AbstractCoulombFriction):
    """Coulomb friction of a cart on its rail (Florian's corrected cart-pole friction).

    The rail's normal force on the cart is the weight of everything the cart carries less
    the vertical acceleration of its links' masses, `N = g M_xx + (dV/dq q'' + q_dot^T
    d2V/dq2 q_dot) / g`: `M_xx` (the mass matrix's cart entry) is the total mass, and the
    gravitational potential `V = g sum_i m_i h_i` gives the heights' second derivatives.
    For the cart-pole it is Florian's `N_c = (m_c + m_p) g - m_p l (theta'' sin theta +
    theta_dot^2 cos theta)`. Defaults: Barto, Sutton and Anderson's `mu_c = 0.0005` for both
    coefficients. The dynamics need `gravity` and `energy` too.
    """

    coordinate: ClassVar[int] = 0
    cart_static_friction: Scalar = eqx.field(default=0.0005, converter=NONNEGATIVE)
    cart_kinetic_friction: Scalar = eqx.field(default=0.0005, converter=NONNEGATIVE)

    @property
    def static_friction(self) -> Scalar:
        return self.cart_static_friction

    @property
    def kinetic_friction(self) -> Scalar:
        return self.cart_kinetic_friction

    # `dynamics: Any`: duck-typed, whatever has the fields `check` asks for.
    def normal_force(self, dynamics: Any, y: State, acceleration: Float[Array, " q"]) -> Scalar:
        q, q_dot = dynamics.coordinates(y)
        if callable(getattr(dynamics, "potential_energy", None)):
            # The dynamics' own (the chains'): the same values, without differentiating the
            # kinetic terms at zero velocity, twice, in every gradient program.
            potential = lambda p: dynamics.potential_energy(with_coordinates(dynamics, y, positions=p))
        else:
            potential = lambda p: dynamics.energy(
                with_coordinates(dynamics, y, positions=p, velocities=jnp.zeros_like(q_dot))
            )
        slope, curvature = jax.jvp(jax.grad(potential), (q,), (q_dot,))
        heights = (slope @ acceleration + curvature @ q_dot) / dynamics.gravity
        return dynamics.gravity * mass_matrix(dynamics, y)[0, 0] + heights

    def check(self, dynamics: AbstractDynamics) -> None:
        super().check(dynamics)
        if not getattr(dynamics, "has_cart", False):
            raise ValueError(f"CartFriction acts on a cart's position, and {type(dynamics).__name__} has no cart")
        for name in ("gravity", "energy"):
            if not hasattr(dynamics, name):
                raise ValueError(f"CartFriction needs dynamics with {name}, and {type(dynamics).__name__} has none")


@final
class PlaneFriction(AbstractCoulombFriction):
    """Coulomb friction of a block on an inclined plane (`SlidingBlockDynamics`): `N = m g cos(alpha)`."""

    coordinate: ClassVar[int] = 0
    static_friction: Scalar = eqx.field(default=0.5, converter=NONNEGATIVE)
    kinetic_friction: Scalar = eqx.field(default=0.3, converter=NONNEGATIVE)

    # `dynamics: Any`: duck-typed, whatever has the fields `check` asks for.
    def normal_force(self, dynamics: Any, y: State, acceleration: Float[Array, " q"]) -> Scalar:
        del y, acceleration
        return dynamics.mass * dynamics.gravity * jnp.cos(dynamics.incline)

    def check(self, dynamics: AbstractDynamics) -> None:
        super().check(dynamics)
        if not hasattr(dynamics, "incline"):
            raise ValueError(f"PlaneFriction acts on a block on a plane, and {type(dynamics).__name__} has none")


__all__ = ["AbstractCoulombFriction", "CartFriction", "PlaneFriction"]
