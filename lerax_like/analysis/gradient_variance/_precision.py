"""How fast a rollout's gradient loses precision, float32 against float64, and the horizon where
the first-order estimator's variance overtakes the zeroth-order one's.

The envs come in pairs by dtype, each with its start: `{"float64": (env, y0), "float32": (env,
y0)}`, built by the study's run; the cost's weights are passed as values.
"""

import math
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..._types import Array
from ...env import AbstractEnv
from ._objective import nominal_parameters, objective, stage_costs


EnvPair = Mapping[str, tuple[AbstractEnv, Array]]
"""The study's env and its start in float64 and in float32, by the dtype's name."""


def truncated_gradients(
    env: AbstractEnv, y0: Array, kind: str, theta: Array, horizon: int, *, state_weight: float, action_weight: float
) -> np.ndarray:
    """Row `h - 1`: the gradient of `f` over the first `h` steps, for every `h <= horizon`.

    One reverse-mode Jacobian of the running cost: open loop, `theta` has `horizon` steps
    and row `h - 1` is zero beyond step `h - 1`.
    """
    costs = stage_costs(env, y0, kind, horizon, state_weight, action_weight)
    running = lambda t: jnp.cumsum(costs(t, horizon)[0])  # noqa: E731
    jacobian = jax.jit(jax.jacrev(running))(theta)
    return np.asarray(jacobian, dtype=np.float64).reshape(horizon, -1)


def _relative_errors(exact: np.ndarray, approximate: np.ndarray) -> np.ndarray:
    """Row by row, `|approximate - exact| / |exact|`; infinite where that is not finite."""
    scale = np.linalg.norm(exact, axis=1)
    error = np.linalg.norm(approximate - exact, axis=1) / np.where(scale > 0, scale, np.nan)
    return np.where(np.isfinite(error), error, np.inf)


def precision_loss(
    envs: EnvPair, solver: str, kind: str, gain64: np.ndarray, horizon: int, *, state_weight: float,
    action_weight: float,
) -> dict[str, Any]:
    """float32 against float64: the relative error of the float32 gradient at the nominal
    `theta` for every horizon up to `horizon`, and the horizons at which its correct digits
    (`-log10` of the relative error) fall below 6, 4, 2 and 1. `solver` labels the entry.

    "Lost its leading correct digit" is a relative error above 0.1.
    """
    gradients = {}
    for dtype in ("float64", "float32"):
        env, y0 = envs[dtype]
        theta = nominal_parameters(env, kind, horizon, jnp.asarray(gain64))
        gradients[dtype] = truncated_gradients(
            env, y0, kind, theta, horizon, state_weight=state_weight, action_weight=action_weight
        )
    error = _relative_errors(gradients["float64"], gradients["float32"])
    digits = -np.log10(np.maximum(error, 1e-300))

    def first_below(threshold):
        index = np.nonzero(digits < threshold)[0]
        return int(index[0]) + 1 if index.size else None

    return {
        "solver": solver,
        "policy": kind,
        "horizons_searched": horizon,
        "relative_error": error.tolist(),
        "first_digit_lost_horizon": first_below(1.0),
        "digits_below_horizon": {str(t): first_below(t) for t in (6, 4, 2, 1)},
    }


def precision_at_horizons(
    envs: EnvPair, solver: str, kind: str, gain64: np.ndarray, horizons: Sequence[int], *, state_weight: float,
    action_weight: float,
) -> dict[str, Any]:
    """float32 against float64 at the given horizons only: the gradient of `f` over each
    horizon, one reverse pass per horizon and dtype, its relative error, the first of
    `horizons` at which the float32 gradient has lost its leading correct digit (relative
    error above 0.1, or a non-finite gradient), and whether every solve of each rollout
    succeeded (a failed solve holds its state: see `stage_costs`). `solver` labels the entry.

    `precision_loss` does every horizon up to the longest with one Jacobian of the running
    cost; that Jacobian needs as many reverse passes as steps, which through adaptive
    solves (the end stops' Tsit5) takes minutes per policy. This costs `len(horizons)`.
    Run it with float64 enabled (as `run_gradient_variance` runs).
    """
    horizons = sorted(int(h) for h in horizons)
    gradients, solves_ok = {}, {}
    for dtype in ("float64", "float32"):
        env, y0 = envs[dtype]
        theta = nominal_parameters(env, kind, horizons[-1], jnp.asarray(gain64))
        costs = stage_costs(env, y0, kind, horizons[-1], state_weight, action_weight)
        value_and_gradient = jax.jit(jax.value_and_grad(objective(costs), has_aux=True))
        results = [value_and_gradient(theta, h) for h in horizons]
        gradients[dtype] = np.stack([np.asarray(g, dtype=np.float64).ravel() for (_, _), g in results])
        solves_ok[dtype] = [bool(ok) for (_, ok), _ in results]
    error = _relative_errors(gradients["float64"], gradients["float32"])
    lost = [h for h, e in zip(horizons, error) if e > 0.1]
    return {
        "solver": solver,
        "policy": kind,
        "horizons": horizons,
        "relative_error": error.tolist(),
        "first_digit_lost_horizon": lost[0] if lost else None,
        "float64_solves_ok": solves_ok["float64"],
        "float32_solves_ok": solves_ok["float32"],
    }


def _crossing(horizons: np.ndarray, log_difference: np.ndarray) -> float | None:
    """The horizon where `log_difference` first turns positive (log-linear interpolation),
    the first horizon if it already is, None if it never does."""
    if log_difference[0] >= 0:
        return float(horizons[0])
    for (h0, d0), (h1, d1) in zip(zip(horizons, log_difference), zip(horizons[1:], log_difference[1:])):
        if d1 >= 0:
            return float(h0 + (h1 - h0) * (-d0) / (d1 - d0))
    return None


def variance_crossover(
    horizons: Sequence[int], first: Sequence[float], zeroth: Sequence[float], exponent: float, dt: float
) -> dict[str, Any]:
    """Where the first-order variance overtakes the zeroth-order one: measured, and
    predicted from the Lyapunov exponent.

    The prediction takes the first-order variance at the shortest horizon and lets it grow
    like `exp(2 lambda t)` (a gradient through a flow grows with its tangent map), against
    the measured zeroth-order variance (interpolated between horizons). The measured
    growth rate is the least-squares slope of `log(variance) / 2` against `t = H dt`.
    Agreement: both crossovers None, or within a factor of 2 of each other.
    """
    h = np.asarray(horizons, dtype=float)
    log_first = np.log(np.asarray(first, dtype=float))
    log_zeroth = np.log(np.asarray(zeroth, dtype=float))
    measured = _crossing(h, log_first - log_zeroth)
    predicted_first = log_first[0] + 2 * exponent * (h - h[0]) * dt
    predicted = _crossing(h, predicted_first - log_zeroth)
    growth = float(np.polyfit(h * dt, 0.5 * log_first, 1)[0]) if len(h) > 1 else math.nan
    if measured is None or predicted is None:
        agree = measured is None and predicted is None
    else:
        agree = bool(max(measured, predicted) <= 2 * min(measured, predicted))
    return {
        "measured_horizon": measured,
        "predicted_horizon": predicted,
        "agree": agree,
        "lyapunov_exponent": exponent,
        "variance_growth_rate": growth,
    }
