"""The Gymnasium layer's input checks, on the host, once: actions into the arrays the
compiled steps take, and assigned states.

An action that cannot be applied (a discrete one out of range or not an integer, a
non-finite continuous one) is refused with a `ValueError` naming the action and the
space, raised explicitly so that it holds under `python -O` (Gymnasium's own envs
`assert`). A finite continuous action outside the box is applied: the scenes clip it,
as Gymnasium's envs do.
"""

import math

import gymnasium
import numpy as np


def _integer_rule(space: gymnasium.spaces.Discrete) -> str:
    return f"an integer from {space.start} to {space.start + space.n - 1}"


def check_action(space: gymnasium.spaces.Discrete | gymnasium.spaces.Box, action) -> np.ndarray | np.int64:
    """One env's `action` in `space`: an int64 scalar (Discrete) or a float64 array of the box's shape."""
    if isinstance(space, gymnasium.spaces.Discrete):
        # `space.contains(action)`, which Gymnasium's CartPole asserts, in half its time.
        integer = isinstance(action, (int, np.integer)) or (
            isinstance(action, np.ndarray) and action.dtype.kind in "iu" and action.shape == ()
        )
        if not (integer and space.start <= action < space.start + space.n):
            raise ValueError(f"action {action!r} is not in {space}: it must be {_integer_rule(space)}")
        return np.int64(action)
    try:
        array = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"action {action!r} is not in {space}: it must be a real array") from error
    if array.size != space.shape[0] or array.ndim > 1:
        raise ValueError(f"the action must have shape {space.shape} ({space}), got {action!r}")
    if not np.isfinite(array).all():
        raise ValueError(
            f"action {array.tolist()} is not in {space}: it must be finite "
            "(finite entries outside the bounds are clipped)"
        )
    return array.reshape(space.shape)


def check_actions(
    space: gymnasium.spaces.Discrete | gymnasium.spaces.Box, actions, num_envs: int, dtype: str
) -> np.ndarray:
    """The actions of `num_envs` envs whose single action space is `space`: int64 of shape
    `(num_envs,)` (Discrete) or `dtype` of shape `(num_envs, *space.shape)`."""
    if isinstance(space, gymnasium.spaces.Discrete):
        array = np.asarray(actions)
        if array.shape != (num_envs,) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions must be an integer array of shape ({num_envs},) (one action in {space} per env), "
                f"got {actions!r}"
            )
        # `self.action_space.contains(actions)`, which Gymnasium's vector CartPole asserts,
        # in a third of its time (the ufuncs' own reductions: `array.min()` adds a Python call).
        if np.minimum.reduce(array) < space.start or np.maximum.reduce(array) >= space.start + space.n:
            index = int(np.flatnonzero((array < space.start) | (array >= space.start + space.n))[0])
            raise ValueError(
                f"actions[{index}] = {array[index]} is not in {space}: every action must be {_integer_rule(space)}"
            )
        return array.astype(np.int64, copy=False)
    try:
        array = np.asarray(actions, dtype=dtype)
    except (TypeError, ValueError) as error:
        raise ValueError(f"actions must be a real array, got {actions!r}") from error
    shape = (num_envs, *space.shape)
    if array.size != math.prod(shape):  # math.prod: np.prod of a tuple costs more than the rest of the check
        raise ValueError(f"the actions must have shape {shape}, got an array of shape {array.shape}")
    array = array.reshape(shape)
    # A NaN or an infinity makes the sum non-finite, so a finite sum (the common case, one
    # reduction) clears every entry; a non-finite one (perhaps an overflow of finite
    # entries) is decided entry by entry.
    if not math.isfinite(np.add.reduce(array, axis=None)) and not np.isfinite(array).all():
        index = int(np.flatnonzero(~np.isfinite(array).all(axis=tuple(range(1, array.ndim))))[0])
        raise ValueError(
            f"actions[{index}] = {array[index].tolist()} is not in {space}: every action must be finite "
            "(finite entries outside the bounds are clipped)"
        )
    return array


def check_state(value, shape: tuple[int, ...], dtype: str, what: str) -> np.ndarray:
    """`value` as a finite array of `shape` and `dtype` (a copy), refused by the name `state`;
    `what` says what the shape is."""
    try:
        state = np.array(value, dtype=dtype)
    except (TypeError, ValueError) as error:
        raise TypeError(f"state must be a real array of shape {shape}, got {value!r}") from error
    if state.shape != shape:
        raise ValueError(f"state must have shape {shape} ({what}), got shape {state.shape}")
    if not np.isfinite(state).all():
        raise ValueError(f"state must be finite, got {state.tolist()}")
    return state
