"""The studies' tables for the terminal: rows in, fixed-width text out (nothing is written here).

`format_table` and `format_orders` for the work-precision study, `format_gradient_table` for
the gradient-accuracy study, `format_gradient_variance_table` for the gradient-variance study.
"""

import math
from collections.abc import Sequence
from typing import Any

from .convergence import ORDER_DISAGREEMENT
from .recording import fixed_width_table
from .verdict import UNRESOLVED_SPREAD, UNRESOLVED_TIMING_FACTOR, group_settings, setting_name, timing_unresolved


def _number(value: float, form: str = ".2e") -> str:
    return "" if math.isnan(value) else format(value, form)


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of the rows, for the terminal.

    Settings whose errors and step counts coincide are one line (`group_settings`),
    named by their range; a time marked `~` is not resolved (`timing_unresolved`), as
    the figure marks it hollow. A failed setting shows `failed` for its errors and, in a
    last column, why (`failure`). An `error` or `max_error` at or below the reference's
    floor is marked `*`: it measures the reference, not the solver. A legend under the
    table says what each schedule and column is (`study_legend`).
    """
    header = (
        "schedule", "solver", "setting", "error", "max_error", "linf_error", "l2_error", "seconds",
        "steps (rejected)", "f-evals", "energy drift",
    )
    grouped = group_settings(rows)
    any_failed = any(not row["solver_ok"] for row in grouped)
    if any_failed:
        header += ("failed because",)
    lines = []
    for row in grouped:
        errors = (row["error"], row["max_error"], row.get("linf_error", math.nan), row.get("l2_error", math.nan))
        floor = row.get("reference_floor", math.nan)
        line = (
            row["schedule"], row["label"], row["setting"],
            *(_error(e, floor if i < 2 else math.nan) if row["solver_ok"] else "failed" for i, e in enumerate(errors)),
            f"{row['seconds']:.2e}" + ("~" if timing_unresolved(row) else ""),
            f"{row['steps']:.0f} ({row.get('rejected_steps', 0.0):.0f})",
            _number(row["vector_field_evaluations"], ".0f"), _number(row.get("energy_drift", math.nan)),
        )
        lines.append(line + ((row.get("failure") or ("" if row["solver_ok"] else "unknown"),) if any_failed else ()))
    table = fixed_width_table(header, lines)
    if any(row["members"] > 1 for row in grouped):
        table += "\n.. a range of settings whose errors and step counts coincide: one setting"
    if any(timing_unresolved(row) for row in grouped):
        table += (
            f"\n~ timing not resolved: within {UNRESOLVED_TIMING_FACTOR:g}x of an empty compiled call, or repeats "
            f"differing by more than {UNRESOLVED_SPREAD:.0%}; compare f-evals instead"
        )
    return table + "\n" + study_legend(grouped)


def _error(value: float, floor: float) -> str:
    return f"{value:.2e}" + ("*" if value <= floor else "")


SCHEDULE_WORDS = {
    "recorded": "a seeded random action from the action space at each env step",
    "zero": "no input (energy drift measured where the scene conserves energy)",
    "constant": "one action held throughout",
}
"""What each action schedule of a study is, in words (`StudyConfig.schedules`)."""


def study_legend(rows: Sequence[dict[str, Any]]) -> str:
    """What the table's schedules and columns are, from the rows' own batch, horizon and floors."""
    first = rows[0] if rows else {}
    batch, horizon = first.get("batch", "?"), first.get("horizon", "?")
    schedules = dict.fromkeys(row["schedule"] for row in rows)
    lines = [f"schedule {name}: {SCHEDULE_WORDS.get(name, 'actions as configured')}" for name in schedules]
    lines += [
        f"error: max-norm of the state error at the final time, the worst of a batch of {batch} starts; max_error: "
        "the same, the largest at any env step's end; linf_error, l2_error: max and root mean square over a dense "
        "grid inside the env steps (the solver's own interpolation); all against SciPy's reference",
        f"seconds: the fastest of the repeats of one compiled run of the batch of {batch} over {horizon} env steps; "
        "steps (rejected): accepted (rejected) solver steps per trajectory; f-evals: vector-field evaluations per "
        "trajectory",
    ]
    floors = {row["schedule"]: row.get("reference_floor", math.nan) for row in rows}
    if any(math.isfinite(floor) for floor in floors.values()):
        shown = ", ".join(f"{name} {floor:.1e}" for name, floor in floors.items() if math.isfinite(floor))
        lines.append(f"* at or below the reference's floor ({shown}): the error is the reference's, not the solver's")
    return "\n".join(lines)


def format_orders(orders: Sequence[dict[str, Any]]) -> str:
    """The fitted orders, one line per schedule and fixed-step solver; in words where none was fitted."""
    if not orders:
        return "(none: no solver in this study runs at fixed steps)"
    width = max((len(str(entry["solver"])) for entry in orders), default=9)
    lines = []
    for entry in orders:
        head = f"{entry['schedule']:>9} {entry['solver']:<{width}}"
        expected = f" (method order {entry['method_order']:g})" if "method_order" in entry else ""
        if entry["order"] is None or math.isnan(entry["order"]):
            lines.append(f"{head} order {entry.get('note', 'not measured')}{expected}")
            continue
        flag = ""
        if entry.get("disagrees"):
            flag = (f"  !! disagrees with the declared order {entry['method_order']:g} by "
                    f"{abs(entry['order'] - entry['method_order']):.2f} (> {ORDER_DISAGREEMENT:g})")
        parts = [f"{head} order {entry['order']:.2f} ({entry['points']} points){expected}{flag}"]
        for name in ("energy_drift_order", "momentum_drift_order"):
            if name in entry and entry[name] is not None and not math.isnan(entry[name]):
                parts.append(f"{name.replace('_order', '').replace('_', ' ')} order {entry[name]:.2f}")
        lines.append(", ".join(parts))
    return "\n".join(lines)


def format_gradient_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of a gradient study's rows, for the terminal."""
    header = ("solver", "setting", "gradient error", "seconds", "solver ok")
    return fixed_width_table(header, (
        (row["label"], setting_name(row), f"{row['error']:.2e}", f"{row['seconds']:.2e}", str(row["solver_ok"]))
        for row in rows
    ))


def format_gradient_variance_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of a gradient-variance study's rows, for the terminal."""
    header = ("solver", "policy", "H", "sigma", "estimator", "norm", "variance", "bias (se)")
    return fixed_width_table(header, (
        (r["solver"], r["policy"], str(r["horizon"]), f"{r['sigma']:g}", r["estimator"],
         f"{r['gradient_norm']:.3g}", f"{r['variance']:.3g}", f"{r['bias']:.2g} ({r['bias_standard_error']:.2g})")
        for r in rows
    ))


__all__ = ["format_gradient_table", "format_gradient_variance_table", "format_orders", "format_table", "study_legend"]
