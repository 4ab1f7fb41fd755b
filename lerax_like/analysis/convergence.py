"""Convergence orders fitted from a study's fixed-step rows."""

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np


# Accumulated float64 round-off over thousands of steps sits around here; errors below
# it say nothing about the method's order.
ROUNDOFF_FLOOR = 1e-12

ORDER_DISAGREEMENT = 0.3
"""A fitted order further than this from the method's declared order is flagged
(`disagrees`): the method, or the order it declares, is wrong, or the sweep misses the
asymptotic range (which `points` and the figure tell apart)."""


def fit_order(
    step_sizes: Sequence[float], errors: Sequence[float], *, floor: float = 0.0, ceiling: float = 1e-2
) -> tuple[float, int]:
    """Slope of `log(error)` on `log(step_size)`, fitted to `floor < error < ceiling`.

    Returns `(slope, points used)`; the slope is NaN with fewer than two points. Errors
    above `ceiling` are outside the asymptotic regime; errors below `floor` are
    dominated by the reference's error or by round-off.
    """
    h = np.asarray(step_sizes, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    keep = np.isfinite(e) & (e > floor) & (e < ceiling)
    if np.count_nonzero(keep) < 2:
        return math.nan, int(np.count_nonzero(keep))
    slope = np.polyfit(np.log(h[keep]), np.log(e[keep]), 1)[0]
    return float(slope), int(np.count_nonzero(keep))


def why_no_order(
    step_sizes: Sequence[float], errors: Sequence[float], *, floor: float, ceiling: float
) -> str:
    """In words, why fewer than two errors lie in the asymptotic range `(floor, ceiling)`."""
    pairs = sorted(
        ((h, e) for h, e in zip(step_sizes, errors) if math.isfinite(e)), key=lambda pair: pair[0], reverse=True
    )
    if not pairs:
        return "not measured: every solve failed"
    values = [e for _, e in pairs]
    span = f"errors {min(values):.2g} to {max(values):.2g} at steps {pairs[0][0]:.3g} to {pairs[-1][0]:.3g}"
    if all(e >= ceiling for e in values):
        words = (
            f"not in the asymptotic range: {span}, all above {ceiling:g}, so no order can be fitted; "
            "smaller steps are needed"
        )
        falling = all(b <= a for a, b in zip(values, values[1:]))
        if not falling:
            words += (
                " (the error does not fall steadily as the step shrinks: at these steps the solution is "
                "qualitatively wrong, e.g. a pendulum near its separatrix ending a turn away)"
            )
        return words
    if all(e <= floor for e in values):
        return f"not measured: {span}, all at or below the reference and round-off floor {floor:.1g}"
    return (
        f"not measured: {span}, fewer than two of them between the floor {floor:.1g} and {ceiling:g}; "
        "a finer sweep of steps is needed"
    )


def convergence_orders(rows: Iterable[dict[str, Any]], *, ceiling: float = 1e-2) -> list[dict[str, Any]]:
    """Per schedule and fixed-step solver: fitted orders of the error and of the invariant drifts.

    The error is fitted between `max(10 * reference floor, ROUNDOFF_FLOOR)` and
    `ceiling`; energy and momentum drifts (zero input only) between `ROUNDOFF_FLOOR` and
    `ceiling`. Rows of a gradient study (no schedule, no `max_error`, no drifts) get
    the order of their `error`, the gradient's, alone.
    """
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for row in rows:
        if row["controller"] != "ConstantStepSize":
            continue
        groups.setdefault((row["scene"], row.get("schedule", ""), row["solver"]), []).append(row)
    orders = []
    for (scene, schedule, solver), group in groups.items():
        group = sorted(group, key=lambda row: row["dt"])
        step_sizes = [row["dt"] for row in group]
        floor = max(10 * max(row["reference_floor"] for row in group), ROUNDOFF_FLOOR)
        entry: dict[str, Any] = {"scene": scene, "schedule": schedule, "solver": solver}
        errors = [row["error"] for row in group]
        entry["order"], entry["points"] = fit_order(step_sizes, errors, floor=floor, ceiling=ceiling)
        if "order" in group[0] and not math.isnan(group[0]["order"]):
            entry["method_order"] = group[0]["order"]
        if entry["points"] < 2:
            entry["order"] = None  # JSON null, not NaN: there is no measurement
            entry["note"] = why_no_order(step_sizes, errors, floor=floor, ceiling=ceiling)
        elif "method_order" in entry:
            entry["disagrees"] = bool(abs(entry["order"] - entry["method_order"]) > ORDER_DISAGREEMENT)
        if "max_error" in group[0]:
            entry["max_error_order"], _ = fit_order(
                step_sizes, [row["max_error"] for row in group], floor=floor, ceiling=ceiling
            )
        for name in ("energy_drift", "momentum_drift"):
            values = [row.get(name, math.nan) for row in group]
            if all(math.isnan(v) for v in values):
                continue
            entry[f"{name}_order"], _ = fit_order(step_sizes, values, floor=ROUNDOFF_FLOOR, ceiling=ceiling)
        for name, value in entry.items():
            if name.endswith("order") and isinstance(value, float) and math.isnan(value):
                entry[name] = None  # JSON null, not NaN: nothing was measured
        orders.append(entry)
    return orders
