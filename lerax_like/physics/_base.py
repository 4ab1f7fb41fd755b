import abc
from typing import TYPE_CHECKING, ClassVar

import equinox as eqx

from .._fields import AbstractParametrised
from .._types import Array, Float, Input, Scalar, ScalarLike, State


class AbstractDynamics(AbstractParametrised):
    """Physics as a vector field `dy/dt = f(t, y, u)`.

    Subclasses declare their physical parameters as fields (`eqx.field(converter=RANGE)`:
    differentiable leaves, checked by name at construction) and implement `vector_field`.
    They know nothing of rewards, observations, action spaces or rendering: those belong
    to a scene.

    Every dynamics declares `velocity_indices`: for a second-order (mechanical) system
    the components of its state that are velocities (the others are positions), which
    partitioned solvers such as `SemiImplicitEuler` need; None for a first-order system,
    or where the layout depends on the instance (a chain's number of links).
    """

    if TYPE_CHECKING:  # equinox's `AbstractClassVar` reads as a dataclass field to a type checker
        velocity_indices: ClassVar[tuple[int, ...] | None]
    else:
        velocity_indices: eqx.AbstractClassVar[tuple[int, ...] | None]

    @abc.abstractmethod
    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        """The time derivative of the state `y` under the physical input `u`."""


def require_attributes(addon: object, dynamics: AbstractDynamics, names: tuple[str, ...], purpose: str) -> None:
    """Refuse, naming each one missing, dynamics without the attributes an add-on reads (`purpose`: what for)."""
    missing = [name for name in names if not hasattr(dynamics, name)]
    if missing:
        raise ValueError(
            f"{type(addon).__name__} needs dynamics with {' and '.join(missing)} ({purpose}), "
            f"and {type(dynamics).__name__} has none"
        )


class AbstractConservativeDynamics(AbstractDynamics):
    """Dynamics with an energy that is conserved when the input is zero."""

    @abc.abstractmethod
    def energy(self, y: State) -> Scalar:
        """Total mechanical energy of the state `y`."""

    @property
    def conserves_energy(self) -> bool:
        """Whether `energy` is conserved under zero input (False for a variant of the
        equations that drops a term, such as Acrobot's `equations="nips"`)."""
        return True


class AbstractChainDynamics(AbstractConservativeDynamics):
    """A chain of rigid links hinged one on the next, from a fixed pivot or from a cart.

    Its generalised coordinates are `q = [x, theta_1, ..., theta_n]` with a cart on a rail
    (`has_cart`), `q = [theta_1, ..., theta_n]` without; the angles are absolute, from
    upright, link 1 hinged on the pivot or the cart and link `i` on link `i - 1`. This is
    what the generalised-force add-ons of `lerax_like.physics.forces` act on: they read
    `(q, q_dot)` from `coordinates` and hand their forces to `forced_vector_field`.
    """

    has_cart: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def coordinates(self, y: State) -> tuple[Float[Array, " q"], Float[Array, " q"]]:
        """The generalised coordinates `q` and their rates `q_dot` in the state `y`."""

    @abc.abstractmethod
    def forced_vector_field(
        self, t: ScalarLike, y: State, u: Input, generalised_force: Float[Array, " q"]
    ) -> State:
        """`vector_field` with the extra generalised force `Q` on `q` added to the input's."""
