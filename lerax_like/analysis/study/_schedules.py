"""The action schedules of a work-precision study and SciPy's reference of each."""

import dataclasses
import time
from typing import Any

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ...env import AbstractEnv
from ...spaces import Box, Discrete
from ..hybrid_reference import hybrid_reference_trajectories
from ..measurements import invariant_drifts
from ..modes_reference import modes_reference_trajectories, uses_modes_reference
from ..reference import dense_reference_trajectories


SCHEDULES = ("zero", "constant", "recorded")


def schedule_inputs(
    env: AbstractEnv, schedule: str, key, horizon: int, *, actions: Any = None, constant_action: Any = None
) -> tuple[np.ndarray, np.ndarray | None]:
    """`(inputs (T, m), actions or None)` of an action schedule over `horizon` env steps.

    `"recorded"` plays `actions` (a seeded random sequence from the action space if None),
    `"constant"` holds `constant_action` (default: a push of half the largest action).
    """
    space = env.action_space
    sample = space.sample(key=key)
    if schedule == "zero":
        u = jnp.zeros_like(env.physical_input(sample))
        return np.repeat(np.asarray(u)[None], horizon, axis=0), None
    if schedule == "constant":
        if constant_action is not None:
            action = jnp.asarray(constant_action)
        elif isinstance(space, Discrete):
            action = jnp.asarray(space.n - 1)
        elif isinstance(space, Box):
            action = 0.5 * jnp.broadcast_to(space.high, space.shape)
        else:
            raise ValueError(f"give constant_action for a scene with action space {space}")
        actions = jnp.broadcast_to(action, (horizon,) + action.shape)
    else:
        if actions is not None:
            actions = jnp.asarray(actions)
            if actions.shape[0] != horizon:
                raise ValueError(f"actions has {actions.shape[0]} steps, horizon is {horizon}")
        else:
            actions = jax.vmap(lambda k: space.sample(key=k))(jr.split(key, horizon))
    inputs = jax.vmap(env.physical_input)(actions)
    return np.asarray(inputs), np.asarray(actions)


def initial_states(env: AbstractEnv, key, batch: int, given: Any = None) -> np.ndarray:
    """The `given` initial states `(batch, n)` in float64, or `batch` drawn from `env.initial`."""
    if given is None:
        y0s = jax.vmap(lambda k: env.initial(key=k).y)(jr.split(key, batch))
    else:
        y0s = jnp.asarray(given, dtype=jnp.float64)
        if y0s.ndim != 2:
            raise ValueError(f"initial_states must have shape (batch, n), got {y0s.shape}")
    return np.asarray(y0s, dtype=np.float64)


def dense_fractions(dense_points: int) -> np.ndarray:
    """The dense error grid inside each env step, as fractions of it (its end is the step's boundary)."""
    return np.arange(1, dense_points) / dense_points


@dataclasses.dataclass
class ScheduleReference:
    """One action schedule of a study and the SciPy reference of its trajectories.

    `inputs` `(T, m)` and `actions` (None for zero input); `states` `(B, T, n)` at the env
    steps' ends and `inside` `(B, T, m - 1, n)` on the dense grid; `floor` bounds the
    reference's own error by its distance from a second solve at ten times the
    tolerance (which is further from the truth than the reference is), `dense_floor` the
    same over the dense grid. `check` holds the discrepancies from an independent
    method, `drifts` the reference's own invariant drifts (zero input).
    """

    schedule: str
    inputs: np.ndarray
    actions: np.ndarray | None
    states: np.ndarray
    inside: np.ndarray
    seconds: float
    floor: float
    dense_floor: float
    check: dict[str, Any]
    drifts: dict[str, float] | None

    def record(self) -> dict[str, Any]:
        """The schedule for the study's JSON record."""
        entry: dict[str, Any] = {
            "inputs": self.inputs.tolist(),
            "actions": None if self.actions is None else self.actions.tolist(),
            "reference_seconds": self.seconds,
            "reference_floor": self.floor,
            "dense_reference_floor": self.dense_floor,
            **self.check,
        }
        if self.drifts is not None:
            entry["reference_drifts"] = self.drifts
        return entry


def _largest_difference(a, a_inside, b, b_inside) -> float:
    return float(max(np.max(np.abs(a - b)), np.max(np.abs(a_inside - b_inside), initial=0.0)))


def schedule_reference(
    env: AbstractEnv, schedule: str, inputs: np.ndarray, actions: np.ndarray | None, y0s: np.ndarray,
    fractions: np.ndarray, *, method: str, tolerance: float, check_method: str | None = None,
) -> ScheduleReference:
    """SciPy's solution of `y0s` under `inputs` with `method` at `rtol = atol = tolerance`, at the env
    steps' ends and at `fractions` inside each; its floor, and its distance from `check_method`'s."""
    dt = float(env.dt)

    def solve(which, tol):
        # Impacts, switches and resets located as events by SciPy too, restarted at each one.
        if uses_modes_reference(env):
            return modes_reference_trajectories(env, y0s, inputs, dt, fractions, method=which, rtol=tol, atol=tol)
        if env.modes() is not None:
            return hybrid_reference_trajectories(env, y0s, inputs, dt, fractions, method=which, rtol=tol, atol=tol)
        return dense_reference_trajectories(env.physics, y0s, inputs, dt, fractions, method=which, rtol=tol, atol=tol)

    start = time.perf_counter()
    states, inside = solve(method, tolerance)
    seconds = time.perf_counter() - start
    looser, looser_inside = solve(method, 10 * tolerance)
    check = {}
    if check_method is not None:
        other, other_inside = solve(check_method, tolerance)
        check = {
            "check_method": check_method,
            "check_discrepancy": float(np.max(np.abs(other - states))),
            "dense_check_discrepancy": _largest_difference(other, other_inside, states, inside),
        }
    return ScheduleReference(
        schedule=schedule, inputs=inputs, actions=actions, states=states, inside=inside, seconds=seconds,
        floor=float(np.max(np.abs(looser - states))),
        dense_floor=_largest_difference(looser, looser_inside, states, inside),
        check=check, drifts=invariant_drifts(env.physics, states, y0s) if measures_drifts(env, schedule) else None,
    )


def measures_drifts(env: AbstractEnv, schedule: str) -> bool:
    """Whether the rows of `schedule` report invariant drifts: zero input, and no dry friction (a
    friction add-on, a disk's floor), which takes energy and momentum by physics (no solver error)."""
    return schedule == "zero" and not (getattr(env, "friction", ()) or getattr(env, "floor", None))
