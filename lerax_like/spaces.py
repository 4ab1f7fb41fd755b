"""Action and observation spaces with JAX-native `sample` and `contains`.

A `Box`'s bounds are NumPy arrays whenever they are known without tracing, also inside a
jitted trainer that closes over its env (`eager_spaces`), so that a trainer can read them
with `np.asarray` (network sizes, clipping constants) as it reads gymnax's. Bounds computed
from traced parameters (an env passed as an argument of `jit` or `vmap`) stay traced.
"""

import abc
import functools

import equinox as eqx
import jax
import jax.core  # `jax.core.Tracer`: imported by name, so that a type checker sees the module
import jax.numpy as jnp
import numpy as np
import jax.random as jr

from ._types import Array, ArrayLike, BoolScalar, Key


class AbstractSpace(eqx.Module):
    shape: eqx.AbstractVar[tuple[int, ...]]
    """The shape of an element (`()` for a discrete space)."""

    @abc.abstractmethod
    def sample(self, *, key: Key) -> Array:
        """A random element of the space."""

    @abc.abstractmethod
    def contains(self, x: ArrayLike) -> BoolScalar:
        """Whether `x` lies in the space (traceable: returns a boolean array)."""

    @abc.abstractmethod
    def check(self, x: ArrayLike, name: str) -> Array:
        """`x` as an array, refused (`TypeError`, naming `name` and the space) if its shape
        or dtype does not fit the space. Shapes and dtypes are known at trace time, so this
        fails when a jitted function is traced, not deep inside JAX."""

    @abc.abstractmethod
    def admissible(self, x: Array) -> BoolScalar:
        """Whether `x`, of fitting shape and dtype (`check`), can be applied (traceable):
        a discrete action in range, a continuous one finite. A continuous action outside
        the box is admissible: the scenes clip it, as Gymnasium's envs do."""

    @property
    @abc.abstractmethod
    def rule(self) -> str:
        """What `admissible` requires, in words, for error messages."""


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

    def check(self, x: ArrayLike, name: str) -> Array:
        x = _as_array(x, name, self)
        if x.shape != () or not jnp.issubdtype(x.dtype, jnp.integer):
            raise TypeError(
                f"{name} must be an integer scalar (shape (), an integer dtype) of {self}, "
                f"got shape {x.shape} and dtype {x.dtype}"
            )
        return x

    def admissible(self, x: Array) -> BoolScalar:
        return (x >= 0) & (x < self.n)

    @property
    def rule(self) -> str:
        return f"an integer from 0 to {self.n - 1}"

    def __str__(self) -> str:
        return f"Discrete({self.n})"


class Box(AbstractSpace):
    """The box `low <= x <= high` of a given shape (bounds may be infinite)."""

    # NumPy where the bounds are known without tracing (see the module's docstring).
    low: Array | np.ndarray
    high: Array | np.ndarray
    shape: tuple[int, ...] = eqx.field(static=True)

    def __init__(self, low: ArrayLike, high: ArrayLike, shape: tuple[int, ...] | None = None):
        if shape is None:
            shape = np.broadcast_shapes(np.shape(low), np.shape(high))
        self.shape = tuple(shape)
        self.low = _bound(low, self.shape)
        self.high = _bound(high, self.shape)

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

    def check(self, x: ArrayLike, name: str) -> Array:
        """As the abstract method; a one-element box also takes a scalar (`0.5` for shape
        `(1,)`), which the scenes' `physical_input` reshape."""
        x = _as_array(x, name, self)
        real = jnp.issubdtype(x.dtype, jnp.floating) or jnp.issubdtype(x.dtype, jnp.integer)
        shape_fits = x.shape == self.shape or (x.shape == () and self.shape == (1,))
        if not (real and shape_fits):
            raise TypeError(
                f"{name} must be a real array of shape {self.shape} of {self}, "
                f"got shape {x.shape} and dtype {x.dtype}"
            )
        return x

    def admissible(self, x: Array) -> BoolScalar:
        return jnp.all(jnp.isfinite(x))

    @property
    def rule(self) -> str:
        return "finite in every entry (entries outside the bounds are clipped)"

    def __str__(self) -> str:
        # The bounds may be traced (a scene's torque limit under jit): shown only when concrete.
        bounds = ""
        if not isinstance(self.low, jax.core.Tracer) and not isinstance(self.high, jax.core.Tracer):
            bounds = f"low={np.asarray(self.low).tolist()}, high={np.asarray(self.high).tolist()}, "
        return f"Box({bounds}shape={self.shape})"


def _bound(value: ArrayLike, shape: tuple[int, ...]) -> Array | np.ndarray:
    """A bound in JAX's default float dtype: NumPy when concrete, traced otherwise."""
    dtype = jax.dtypes.canonicalize_dtype(float)
    if isinstance(value, jax.core.Tracer):
        return jnp.broadcast_to(value.astype(dtype), shape)
    return np.broadcast_to(np.asarray(value, dtype=dtype), shape)


def eager_spaces(env_class: type) -> None:
    """Make `env_class`'s own `action_space` and `observation_space` properties compute with
    `jax.ensure_compile_time_eval`: inside a trace, bounds that depend only on concrete
    values (an env closed over by a jitted function) are computed at once, as NumPy."""
    for name in ("action_space", "observation_space"):
        space = env_class.__dict__.get(name)
        if isinstance(space, property):
            setattr(env_class, name, property(_eager(space.fget), doc=space.__doc__))


def _eager(fget):
    @functools.wraps(fget)
    def get(env):
        with jax.ensure_compile_time_eval():
            return fget(env)

    return get


def _as_array(x: ArrayLike, name: str, space: AbstractSpace) -> Array:
    try:
        return jnp.asarray(x)
    except TypeError as error:
        raise TypeError(f"{name} must be an element of {space}, got {x!r}") from error


__all__ = ["AbstractSpace", "Box", "Discrete", "eager_spaces"]
