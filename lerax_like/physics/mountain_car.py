from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import POSITIVE
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

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    gravity: Scalar = eqx.field(default=0.0025, converter=POSITIVE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        position, velocity = y
        # Gymnasium's order of operations (`force + cos(3x) * (-gravity)`).
        return jnp.stack([velocity, u[0] + jnp.cos(3 * position) * (-self.gravity)])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus potential energy per unit mass; conserved when `u = 0` off the walls."""
        position, velocity = y
        return 0.5 * velocity**2 + self.gravity / 3 * jnp.sin(3 * position)
