from typing import TYPE_CHECKING, ClassVar, final

import jax.numpy as jnp

from .._fields import POSITIVE, parameter
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


@final
class MountainCarDynamics(AbstractConservativeDynamics):
    """A car on the hill `h(x) = sin(3x) / 3`, in Moore's (1990) unitless units.

    `dv/dt = u[0] - gravity * cos(3x)`, with `u[0]` the engine's acceleration. Gymnasium's
    MountainCar is one semi-implicit Euler step of this field with `dt = 1` (its time
    unit is the env step), plus a speed limit, the ends of the road and the left wall,
    which the scene declares as its projection.

    State `y = [position, velocity]`.
    """

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import MountainCarDynamicsKeywords

        def __init__(self, **keywords: Unpack[MountainCarDynamicsKeywords]) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    gravity: Scalar = parameter(0.0025, POSITIVE)


    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        position, velocity = y
        # Gymnasium's order of operations (`force + cos(3x) * (-gravity)`).
        return jnp.stack([velocity, u[0] + jnp.cos(3 * position) * (-self.gravity)])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus potential energy per unit mass; conserved when `u = 0` off the walls."""
        position, velocity = y
        return 0.5 * velocity**2 + self.gravity / 3 * jnp.sin(3 * position)
