"""Gymnasium spaces from the scenes' spaces, in Gymnasium's float32 convention."""

import gymnasium
import numpy as np

from ..spaces import AbstractSpace, Box, Discrete


def to_gymnasium_space(space: AbstractSpace) -> gymnasium.spaces.Discrete | gymnasium.spaces.Box:
    if isinstance(space, Discrete):
        return gymnasium.spaces.Discrete(space.n)
    if isinstance(space, Box):
        low = np.asarray(space.low, dtype=np.float32)
        high = np.asarray(space.high, dtype=np.float32)
        return gymnasium.spaces.Box(low=low, high=high, shape=space.shape, dtype=np.float32)
    raise TypeError(f"no Gymnasium counterpart for the space {space!r}")
