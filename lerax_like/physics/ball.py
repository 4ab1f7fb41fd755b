"""A point mass in the vertical plane under gravity, and the floor and wall it bounces on."""

from typing import TYPE_CHECKING, ClassVar, final

import jax.numpy as jnp

from .._fields import FINITE, POSITIVE, parameter
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from ._base import AbstractConservativeDynamics
from .contact import RESTITUTION, AbstractImpulseContact


@final
class BallDynamics(AbstractConservativeDynamics):
    """A ball (a point mass `mass`) in the vertical plane, under `gravity` and a thrust.

    State `y = [x, z, x_dot, z_dot]` (m, m/s; `z` up); input `u = [F_x, F_z]` (N).
    `x'' = F_x / mass`, `z'' = F_z / mass - gravity`. Generalised coordinates `q = [x, z]`.
    """

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source
        from typing import Unpack

        from lerax_like._keywords import BallDynamicsKeywords

        def __init__(self, **keywords: Unpack[BallDynamicsKeywords]) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    velocity_indices: ClassVar[tuple[int, ...]] = (2, 3)

    mass: Scalar = parameter(1.0, POSITIVE)
    gravity: Scalar = parameter(9.81, POSITIVE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        acceleration = u / self.mass - jnp.stack([jnp.zeros_like(self.gravity), self.gravity])
        return jnp.concatenate([y[2:], acceleration])

    def coordinates(self, y: State) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
        return y[:2], y[2:]

    def energy(self, y: State) -> Scalar:
        return 0.5 * self.mass * (y[2] ** 2 + y[3] ** 2) + self.mass * self.gravity * y[1]


@final
class FloorAndWall(AbstractImpulseContact):
    """A floor at `z = 0` and a wall at `x = wall_position` (the ball on its left), rigid.

    Gaps `[z, wall_position - x]`; restitution `e` on both; below `min_rebound_speed`
    (m/s) the ball rests on the surface until the surface would have to pull.
    """

    if TYPE_CHECKING:  # the constructor as a type checker sees it; written by python -m lerax_like._constructor_source

        def __init__(
            self,
            *,
            max_events: int = 16,
            restitution: ScalarLike = 0.8,
            wall_position: ScalarLike = 1.0,
            min_rebound_speed: ScalarLike = 0.01,
        ) -> None: ...
    # (end of the constructor written by python -m lerax_like._constructor_source)

    restitution: Scalar = parameter(0.8, RESTITUTION)
    wall_position: Scalar = parameter(1.0, FINITE)
    min_rebound_speed: Scalar = parameter(1e-2, POSITIVE)

    def gaps(self, dynamics: BallDynamics, y: State) -> Float[Array, " 2"]:
        x, z = dynamics.coordinates(y)[0]
        return jnp.stack([z, self.wall_position - x])


__all__ = ["BallDynamics", "FloorAndWall"]
