from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import FINITE, POSITIVE, Range
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics
from .contact import RESTITUTION, AbstractImpulseContact

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

    def mass_matrix(self, y: State) -> Float[Array, "1 1"]:
        """`M = [[mass]]`: the Hessian of `energy` in the velocity, in closed form."""
        return self.mass * jnp.ones((1, 1), y.dtype)


@final
class PlaneEnd(AbstractImpulseContact):
    """A wall across the plane at `plane_end` (m along it, the block below it), rigid.

    Gap `plane_end - s`; the block rebounds with `restitution` `e` times its speed, and below
    `min_rebound_speed` (m/s) it would rest against the wall. Beside `PlaneFriction` the two are
    one located-event loop (`lerax_like.contact_friction`), which reports such a rest as a failed
    step rather than model a block held against a wall by friction.
    """

    restitution: Scalar = eqx.field(converter=RESTITUTION, kw_only=True)
    plane_end: Scalar = eqx.field(default=2.0, converter=FINITE)
    min_rebound_speed: Scalar = eqx.field(default=1e-3, converter=POSITIVE)

    def gaps(self, dynamics: SlidingBlockDynamics, y: State) -> Float[Array, " 1"]:
        return jnp.stack([self.plane_end - dynamics.coordinates(y)[0][0]])

    def check(self, dynamics) -> None:
        super().check(dynamics)
        if not hasattr(dynamics, "incline"):
            raise ValueError(f"PlaneEnd stops a block on a plane, and {type(dynamics).__name__} has none")
