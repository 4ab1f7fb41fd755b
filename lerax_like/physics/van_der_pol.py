from typing import ClassVar, final

import equinox as eqx
import jax.numpy as jnp

from .._fields import NONNEGATIVE
from .._types import Input, Scalar, ScalarLike, State
from ._base import AbstractDynamics


@final
class VanDerPolDynamics(AbstractDynamics):
    """The forced Van der Pol oscillator (van der Pol, 1926).

    State `y = [x, v]`, input `u = [force]`:

        x' = v
        v' = mu (1 - x^2) v - x + u

    For `mu` of order 1 the limit cycle is a smooth oscillation of amplitude about 2. For
    `mu >> 1` it is a relaxation oscillation of period about `(3 - 2 ln 2) mu`: slow
    drifts along the branches `|x| > 1` separated by jumps that last `O(1/mu)`; along the
    slow branches the Jacobian has an eigenvalue about `-mu (x^2 - 1)`, so at `mu = 1e3`
    an explicit solver needs steps of order `1e-3` where an implicit one takes steps of
    order 1.
    """

    velocity_indices: ClassVar[None] = None  # first order in this form

    # mu = 0 is the harmonic oscillator, a valid (if not very interesting) limit.
    mu: Scalar = eqx.field(default=1.0, converter=NONNEGATIVE)

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        x, v = y
        return jnp.stack([v, self.mu * (1 - x**2) * v - x + u[0]])
