from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import POSITIVE, Range
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

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)
    incline: Scalar = eqx.field(default=0.0, converter=INCLINE)

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
