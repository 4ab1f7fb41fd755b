"""Writing a study down: the CSV of its rows, the JSON of its configuration and verdicts, a table.

For the work-precision study of the solutions (`write_study`) and of their gradients
(`write_gradient_study`). Files are written by `recording` (the one writer of studies and
benchmarks), figures drawn by `figures`, verdicts reached by `verdict`; their public
names are re-exported here.
"""

import math
import os
from collections.abc import Iterable, Sequence
from typing import Any

from .convergence import ORDER_DISAGREEMENT
from .figures import (
    order_guide as order_guide,
    plot_gradient_work_precision as plot_gradient_work_precision,
    plot_work_precision as plot_work_precision,
)
from .recording import (
    PLOT_HINT as PLOT_HINT,
    fixed_width_table,
    matplotlib_available as matplotlib_available,
    read_csv_rows,
    write_record,
)
from .recording import write_csv as write_rows
from .study import StudyResult
from .verdict import (
    UNRESOLVED_SPREAD as UNRESOLVED_SPREAD,
    UNRESOLVED_TIMING_FACTOR as UNRESOLVED_TIMING_FACTOR,
    cheapest_at as cheapest_at,
    failures as failures,
    order_disagreements as order_disagreements,
    group_settings as group_settings,
    setting_name,
    timing_unresolved as timing_unresolved,
)


CSV_COLUMNS = (
    "scene", "schedule", "solver", "label", "order", "controller", "dt", "env_dt", "substeps", "rtol", "atol",
    "error", "max_error", "l2_error", "linf_error", "seconds", "seconds_spread", "timing_floor",
    "steps", "attempted_steps", "rejected_steps", "vector_field_evaluations",
    "energy_drift", "momentum_drift", "solver_ok", "failure", "batch", "horizon", "dtype",
    "reference_method", "reference_tolerance", "reference_floor", "dense_points",
)
"""One row per schedule and solver setting. `solver` is the solver's name (a preset's, or
its class name) and `order` the method's order (empty if unknown). `error` is the
max-norm error at the final time, `max_error` over the env-step ends; `l2_error` (root
mean square) and `linf_error` (maximum) are over a dense grid of `dense_points` per env
step including its end, from the solver's own dense output against SciPy's (as
DiffEqDevTools' `L2` and `Linf`); all maximal over the batch. `seconds` is the minimum
over repeats of the whole batch's run, `seconds_spread` (median - min) / min over the
repeats (empty for a single repeat), `timing_floor` the time of an empty compiled call; `steps` accepted,
`rejected_steps` rejected solver steps and `vector_field_evaluations` per trajectory;
`dt` the solver's step (fixed-step rows); `failure`, where `solver_ok` is False, why the
setting failed and where (`measurements.failure_reason`: step budget exhausted, step size
collapsed, root finder failed, non-finite state)."""


GRADIENT_CSV_COLUMNS = (
    "scene", "solver", "label", "controller", "dt", "env_dt", "substeps", "rtol", "atol", "error", "seconds",
    "solver_ok", "mode", "horizon", "reference_rtol", "reference_floor",
)
"""One row per solver setting of a gradient study. `error` is the relative 2-norm error of
the gradient against the reference; `seconds` the median time of one gradient; `dt` the
solver's step (fixed-step rows); `reference_floor` the reference's own relative error
estimate. The gradients themselves are in the JSON."""


def write_csv(
    rows: Iterable[dict[str, Any]], path: "str | os.PathLike", *, columns: Sequence[str] = CSV_COLUMNS
) -> None:
    """Write a study's rows as CSV (`recording.write_csv` with the study's columns)."""
    write_rows(rows, path, columns=columns)


def read_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a study CSV, numbers parsed (empty cells as NaN)."""
    numeric = {
        "dt", "env_dt", "rtol", "atol", "order", "error", "max_error", "l2_error", "linf_error", "seconds",
        "seconds_spread", "timing_floor", "steps", "attempted_steps", "rejected_steps",
        "vector_field_evaluations", "energy_drift", "momentum_drift", "reference_tolerance", "reference_floor",
    }
    rows = []
    for raw in read_csv_rows(path):
        row: dict[str, Any] = dict(raw)
        for key in numeric & raw.keys():
            row[key] = float(raw[key]) if raw[key] != "" else math.nan
        for key in ("substeps", "batch", "horizon", "dense_points"):
            if raw.get(key):
                row[key] = int(raw[key])
        row["solver_ok"] = raw.get("solver_ok") == "True"
        rows.append(row)
    return rows


VERDICT_TARGETS = (1e-3, 1e-6, 1e-9)
"""The error levels at which a study names its cheapest setting."""


def write_json(result: StudyResult, path: "str | os.PathLike", **extra) -> None:
    """The study's JSON record: its configuration, references, orders and verdicts.

    `cheapest` is the verdict (`cheapest_at` by its default measure), one per level;
    `cheapest_by_evaluations` the same by evaluations alone and `cheapest_by_seconds` by
    resolved timings alone (None where no resolved timing reached the level).
    """
    record = dict(result.record)
    record["convergence_orders"] = result.convergence_orders()
    record["cheapest"] = {f"{t:.0e}": cheapest_at(result.rows, t) for t in VERDICT_TARGETS}
    record["cheapest_by_seconds"] = {f"{t:.0e}": cheapest_at(result.rows, t, cost="seconds") for t in VERDICT_TARGETS}
    record["cheapest_by_evaluations"] = {
        f"{t:.0e}": cheapest_at(result.rows, t, cost="vector_field_evaluations") for t in VERDICT_TARGETS
    }
    record["order_disagreements"] = order_disagreements(record["convergence_orders"])
    record["failures"] = failures(result.rows)
    record.update(extra)
    write_record(record, path)


def _number(value: float, form: str = ".2e") -> str:
    return "" if math.isnan(value) else format(value, form)


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of the rows, for the terminal.

    Settings whose errors and step counts coincide are one line (`group_settings`),
    named by their range; a time marked `~` is not resolved (`timing_unresolved`), as
    the figure marks it hollow. A failed setting shows `failed` for its errors and, in a
    last column, why (`failure`).
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
        line = (
            row["schedule"], row["label"], row["setting"],
            *(f"{e:.2e}" if row["solver_ok"] else "failed" for e in errors),
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
    return table


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


def write_study(
    result: StudyResult, out: str | os.PathLike, *, plot: bool = True, stem: str | None = None,
    title: str | None = None, **extra,
) -> dict[str, str]:
    """Write `<stem>.csv`, `<stem>.json` and (if `plot`) `<stem>.png` into `out` (stem: the scene).

    Without matplotlib the plot is skipped, not an error: `paths` then has no `"png"`
    and the JSON says `"figure": {"skipped": ...}`. The JSON records the legend's labels
    and the failed settings the figure marks (`"figure": {"failed": ...}`).
    """
    os.makedirs(out, exist_ok=True)
    stem = os.path.join(out, stem or result.config.scene)
    paths = {"csv": stem + ".csv", "json": stem + ".json"}
    write_csv(result.rows, paths["csv"])
    figure_record: dict[str, Any] = {"skipped": "not asked for"}
    if plot:
        if matplotlib_available():
            figure = plot_work_precision(result.rows, stem + ".png", title=title,
                                         fit_ceiling=result.config.fit_ceiling)
            paths["png"] = stem + ".png"
            figure_record = {"path": os.path.basename(paths["png"]), "legend": getattr(figure, "legend_labels"),
                             "failed": getattr(figure, "failed_settings")}
        else:
            figure_record = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    write_json(result, paths["json"], figure=figure_record, **extra)
    return paths


def format_gradient_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of a gradient study's rows, for the terminal."""
    header = ("solver", "setting", "gradient error", "seconds", "solver ok")
    return fixed_width_table(header, (
        (row["label"], setting_name(row), f"{row['error']:.2e}", f"{row['seconds']:.2e}", str(row["solver_ok"]))
        for row in rows
    ))


def write_gradient_study(
    result: StudyResult, out: str | os.PathLike, *, plot: bool = True, stem: str | None = None,
    signs: dict[str, Any] | None = None, **extra,
) -> dict[str, str]:
    """Write a gradient study's `<stem>.csv`, `<stem>.json` and (if `plot`) `<stem>.png` into `out`.

    `result` is what `run_gradient_study` returns; `stem` defaults to `<scene>_gradients`;
    `signs` (from `sensitivity_signs`) goes into the JSON and the plot, `extra` into the JSON.
    """
    os.makedirs(out, exist_ok=True)
    stem = os.path.join(out, stem or f"{result.config.scene}_gradients")
    paths = {"csv": stem + ".csv", "json": stem + ".json"}
    write_csv(result.rows, paths["csv"], columns=GRADIENT_CSV_COLUMNS)
    record = {**result.record, "rows": result.rows, "convergence_orders": result.convergence_orders()}
    if signs is not None:
        record["wrong_sign"] = signs
    if plot and matplotlib_available():
        paths["png"] = stem + ".png"
        plot_gradient_work_precision(result.rows, paths["png"], signs=signs)
    elif plot:
        record["figure"] = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    write_record({**record, **extra}, paths["json"])
    return paths
