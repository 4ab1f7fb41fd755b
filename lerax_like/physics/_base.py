import abc
from typing import ClassVar

import equinox as eqx

from .._fields import AbstractParametrised

from .._types import Input, Scalar, ScalarLike, State


class AbstractDynamics(AbstractParametrised):
    """Physics as a vector field `dy/dt = f(t, y, u)`.

    Subclasses declare their physical parameters as fields (`parameter(default, range)`:
    differentiable leaves, checked by name at construction) and implement `vector_field`. They know nothing of rewards, observations, action
    spaces or rendering: those belong to a scene.

    A second-order (mechanical) system declares `velocity_indices`, the components of
    its state that are velocities (the others are positions): partitioned solvers such
    as `SemiImplicitEuler` need them.
    """

    velocity_indices: ClassVar[tuple[int, ...] | None] = None

    @abc.abstractmethod
    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        """The time derivative of the state `y` under the physical input `u`."""
        raise NotImplementedError


class AbstractConservativeDynamics(AbstractDynamics):
    """Dynamics with an energy that is conserved when the input is zero."""

    @abc.abstractmethod
    def energy(self, y: State) -> Scalar:
        """Total mechanical energy of the state `y`."""
        raise NotImplementedError

    @property
    def conserves_energy(self) -> bool:
        """Whether `energy` is conserved under zero input (False for a variant of the
        equations that drops a term, such as Acrobot's `equations="nips"`)."""
        return True
