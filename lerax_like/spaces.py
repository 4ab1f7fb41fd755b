"""Action and observation spaces with JAX-native `sample` and `contains`."""

import abc

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr

from ._types import Array, ArrayLike, BoolScalar, Key


class AbstractSpace(eqx.Module):
    @abc.abstractmethod
    def sample(self, *, key: Key) -> Array:
        """A random element of the space."""

    @abc.abstractmethod
    def contains(self, x: ArrayLike) -> BoolScalar:
        """Whether `x` lies in the space (traceable: returns a boolean array)."""


class Discrete(AbstractSpace):
    """The integers `{0, 1, ..., n - 1}`."""

    n: int = eqx.field(static=True)

    def __init__(self, n: int):
        if not isinstance(n, int) or n < 1:
            raise ValueError(f"n must be an integer >= 1, got {n!r}")
        self.n = n

    @property
    def shape(self) -> tuple[int, ...]:
        return ()

    def sample(self, *, key: Key) -> Array:
        return jr.randint(key, (), 0, self.n)

    def contains(self, x: ArrayLike) -> BoolScalar:
        x = jnp.asarray(x)
        integral = jnp.issubdtype(x.dtype, jnp.integer) | jnp.all(x == jnp.round(x))
        return (x.shape == ()) & integral & (x >= 0) & (x < self.n)


class Box(AbstractSpace):
    """The box `low <= x <= high` of a given shape (bounds may be infinite)."""

    low: Array
    high: Array
    shape: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, low: ArrayLike, high: ArrayLike, shape: tuple[int, ...] | None = None):
        low = jnp.asarray(low, dtype=float)
        high = jnp.asarray(high, dtype=float)
        if shape is None:
            shape = jnp.broadcast_shapes(low.shape, high.shape)
        self.shape = tuple(shape)
        self.low = jnp.broadcast_to(low, self.shape)
        self.high = jnp.broadcast_to(high, self.shape)

    def sample(self, *, key: Key) -> Array:
        # As Gymnasium: uniform on bounded coordinates, exponential on half-bounded ones,
        # normal on unbounded ones.
        uniform_key, normal_key, exponential_key = jr.split(key, 3)
        dtype = self.low.dtype
        bounded_low = jnp.isfinite(self.low)
        bounded_high = jnp.isfinite(self.high)
        low = jnp.where(bounded_low, self.low, 0.0)
        high = jnp.where(bounded_high, self.high, 0.0)
        uniform = jr.uniform(uniform_key, self.shape, dtype, minval=low, maxval=high)
        normal = jr.normal(normal_key, self.shape, dtype)
        exponential = jr.exponential(exponential_key, self.shape, dtype)
        return jnp.where(
            bounded_low & bounded_high,
            uniform,
            jnp.where(bounded_low, low + exponential, jnp.where(bounded_high, high - exponential, normal)),
        )

    def contains(self, x: ArrayLike) -> BoolScalar:
        x = jnp.asarray(x)
        if x.shape != self.shape:
            return jnp.asarray(False)
        return jnp.all((x >= self.low) & (x <= self.high))


__all__ = ["AbstractSpace", "Box", "Discrete"]
