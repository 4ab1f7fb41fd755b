"""Random starts at a quarter of `jax.random.uniform`'s key work."""

import math

import jax.numpy as jnp
import jax.random as jr
from jaxtyping import ArrayLike, DTypeLike

from ._types import Array, Key


def uniform(key: Key, shape: tuple[int, ...], dtype: DTypeLike, minval: ArrayLike, maxval: ArrayLike) -> Array:
    """Uniform draws in `[minval, maxval)`, each from 16 random bits: four per hash of `key`.

    `jax.random.uniform` hashes the key once per value (threefry, in JAX's default
    partitionable mode), and in a vmapped env step with autoreset that hashing costs more
    than the physics (`benchmarks/profile_step.py`). Each `jax.random.fold_in` here yields
    64 random bits (the first two 32-bit words of the new key), which make four draws: a
    CartPole start costs one hash instead of four.

    The draws lie on a grid of 2**16 points, `(maxval - minval) / 65536` apart: 1.5e-6
    for CartPole's start range of 0.1, far finer than anything a start distribution is
    meant to express. (The Gymnasium layer draws its starts with NumPy, as Gymnasium does.)
    """
    size = math.prod(shape)
    words = jnp.concatenate([jr.key_data(jr.fold_in(key, i)).reshape(-1)[:2] for i in range(-(-size // 4))])
    halves = jnp.stack([words & 0xFFFF, words >> 16], axis=-1).reshape(-1)[:size]
    fraction = halves.astype(dtype) / 65536  # k / 2**16, exact in any float type
    minval = jnp.asarray(minval, dtype)
    maxval = jnp.asarray(maxval, dtype)
    return (minval + (maxval - minval) * fraction.reshape(shape)).astype(dtype)
