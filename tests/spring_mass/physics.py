"""A mass on a linear spring with a linear (viscous) damper, pushed by a force."""

from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp

from lerax_like import NONNEGATIVE, POSITIVE, AbstractConservativeDynamics


@final
class SpringMassDynamics(AbstractConservativeDynamics):
    """`m x'' = -k x - c x' + u`: mass `mass`, spring `stiffness`, damper `damping`, force `u[0]`.

    State `y = [x, x_dot]`. The energy `m x'^2 / 2 + k x^2 / 2` is conserved only without
    damping.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    mass: jax.Array = eqx.field(default=1.0, converter=POSITIVE)
    stiffness: jax.Array = eqx.field(default=4.0, converter=POSITIVE)
    damping: jax.Array = eqx.field(default=0.4, converter=NONNEGATIVE)

    def vector_field(self, t, y: jax.Array, u: jax.Array) -> jax.Array:
        del t
        x, x_dot = y
        x_acc = (u[0] - self.stiffness * x - self.damping * x_dot) / self.mass
        return jnp.stack([x_dot, x_acc])

    def energy(self, y: jax.Array) -> jax.Array:
        x, x_dot = y
        return 0.5 * self.mass * x_dot**2 + 0.5 * self.stiffness * x**2

    @property
    def conserves_energy(self) -> bool:
        # Only a concrete zero conserves: a traced damping may be anything.
        return not isinstance(self.damping, jax.core.Tracer) and bool(self.damping == 0)
