"""A point mass in the vertical plane under gravity, and the floor and wall it bounces on."""

from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import FINITE, POSITIVE
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics
from .contact import RESTITUTION, AbstractImpulseContact


@final
class BallDynamics(AbstractConservativeDynamics):
    """A ball (a point mass `mass`) in the vertical plane, under `gravity` and a thrust.

    State `y = [x, z, x_dot, z_dot]` (m, m/s; `z` up); input `u = [F_x, F_z]` (N).
    `x'' = F_x / mass`, `z'' = F_z / mass - gravity`. Generalised coordinates `q = [x, z]`.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (2, 3)

    mass: Scalar = eqx.field(default=1.0, converter=POSITIVE)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        acceleration = u / self.mass - jnp.stack([jnp.zeros_like(self.gravity), self.gravity])
        return jnp.concatenate([y[2:], acceleration])

    def coordinates(self, y: State) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
        return y[:2], y[2:]

    def energy(self, y: State) -> Scalar:
        return 0.5 * self.mass * (y[2] ** 2 + y[3] ** 2) + self.mass * self.gravity * y[1]

    def mass_matrix(self, y: State) -> Float[Array, "2 2"]:
        """`M = mass I`: the Hessian of `energy` in the velocities, in closed form."""
        return self.mass * jnp.eye(2, dtype=y.dtype)


@final
class FloorAndWall(AbstractImpulseContact):
    """A floor at `z = 0` and a wall at `x = wall_position` (the ball on its left), rigid.

    Gaps `[z, wall_position - x]`; restitution `e` on both; below `min_rebound_speed`
    (m/s) the ball rests on the surface until the surface would have to pull.
    """

    restitution: Scalar = eqx.field(default=0.8, converter=RESTITUTION)
    wall_position: Scalar = eqx.field(default=1.0, converter=FINITE)
    min_rebound_speed: Scalar = eqx.field(default=1e-2, converter=POSITIVE)

    def gaps(self, dynamics: BallDynamics, y: State) -> Float[Array, " 2"]:
        x, z = dynamics.coordinates(y)[0]
        return jnp.stack([z, self.wall_position - x])


__all__ = ["BallDynamics", "FloorAndWall"]
