from typing import TYPE_CHECKING, ClassVar, final

import jax.numpy as jnp
import numpy as np

from .._fields import POSITIVE, Range, parameter
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics


INCLINE = Range(
    "finite and in [0, pi/2) (allowed range [0, pi/2))",
    lambda a: bool(np.all(np.isfinite(a)) and np.all(a >= 0) and np.all(a < np.pi / 2)),
)


@final
class SlidingBlockDynamics(AbstractConservativeDynamics):
    """A block of mass `mass` on a plane inclined at `incline` (rad), pushed along it by `u[0]` newtons.

    State `y = [s, v]`: the position along the plane (m, positive up the slope) and its
    rate. Without friction, `v' = u[0] / mass - gravity sin(incline)`; the plane's dry
    friction is the add-on `lerax_like.physics.friction.PlaneFriction`, which acts through
    `forced_vector_field`.
    """

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import SlidingBlockDynamicsKeywords

        def __init__(self, **keywords: Unpack[SlidingBlockDynamicsKeywords]) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    mass: Scalar = parameter(1.0, POSITIVE)
    gravity: Scalar = parameter(9.81, POSITIVE)
    incline: Scalar = parameter(0.0, INCLINE)

    def coordinates(self, y: State) -> tuple[Float[Array, " 1"], Float[Array, " 1"]]:
        return y[:1], y[1:]

    def forced_vector_field(self, t: ScalarLike, y: State, u: Input, generalised_force: Float[Array, " 1"]) -> State:
        del t
        _, velocity = y
        acceleration = (u[0] + generalised_force[0]) / self.mass - self.gravity * jnp.sin(self.incline)
        return jnp.stack([velocity, acceleration])

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        return self.forced_vector_field(t, y, u, jnp.zeros((1,), y.dtype))

    def energy(self, y: State) -> Scalar:
        """Kinetic plus gravitational potential energy (height `s sin(incline)`)."""
        position, velocity = y
        return 0.5 * self.mass * velocity**2 + self.mass * self.gravity * position * jnp.sin(self.incline)
