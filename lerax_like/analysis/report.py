"""Writing a study down: the CSV of its rows, the JSON of its configuration, the plot, a table.

For the work-precision study of the solutions (`write_study`) and of their gradients
(`write_gradient_study`).
"""

import csv
import json
import math
import os
from collections.abc import Iterable, Sequence
from typing import Any

from .study import StudyResult


CSV_COLUMNS = (
    "scene", "schedule", "solver", "label", "controller", "dt", "env_dt", "substeps", "rtol", "atol",
    "error", "max_error", "seconds", "steps", "attempted_steps", "vector_field_evaluations",
    "energy_drift", "momentum_drift", "solver_ok", "batch", "horizon", "dtype",
    "reference_method", "reference_tolerance", "reference_floor",
)
"""One row per schedule and solver setting. `error` is the max-norm error at the final
time, `max_error` over the whole trajectory (both maximal over the batch); `seconds` the
minimum over repeats of the whole batch's run; `steps` accepted solver steps and
`vector_field_evaluations` per trajectory; `dt` the solver's step (fixed-step rows)."""


GRADIENT_CSV_COLUMNS = (
    "scene", "solver", "label", "controller", "dt", "env_dt", "substeps", "rtol", "atol", "error", "seconds",
    "solver_ok", "mode", "horizon", "reference_rtol", "reference_floor",
)
"""One row per solver setting of a gradient study. `error` is the relative 2-norm error of
the gradient against the reference; `seconds` the median time of one gradient; `dt` the
solver's step (fixed-step rows); `reference_floor` the reference's own relative error
estimate. The gradients themselves are in the JSON."""


def write_csv(
    rows: Iterable[dict[str, Any]], path: str | os.PathLike, *, columns: Sequence[str] = CSV_COLUMNS
) -> None:
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({key: _csv_value(row.get(key, "")) for key in columns})


def _csv_value(value):
    if isinstance(value, float):
        return "" if math.isnan(value) else repr(value)
    return value


def read_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a study CSV, numbers parsed (empty cells as NaN)."""
    numeric = {
        "dt", "env_dt", "rtol", "atol", "error", "max_error", "seconds", "steps", "attempted_steps",
        "vector_field_evaluations", "energy_drift", "momentum_drift", "reference_tolerance", "reference_floor",
    }
    rows = []
    with open(path, newline="") as file:
        for raw in csv.DictReader(file):
            row: dict[str, Any] = dict(raw)
            for key in numeric & raw.keys():
                row[key] = float(raw[key]) if raw[key] != "" else math.nan
            for key in ("substeps", "batch", "horizon"):
                if raw.get(key):
                    row[key] = int(raw[key])
            row["solver_ok"] = raw.get("solver_ok") == "True"
            rows.append(row)
    return rows


def write_json(result: StudyResult, path: str | os.PathLike, **extra) -> None:
    record = dict(result.record)
    record["convergence_orders"] = result.convergence_orders()
    targets = (1e-3, 1e-6, 1e-9)
    record["cheapest_by_seconds"] = {f"{t:.0e}": cheapest_at(result.rows, t) for t in targets}
    record["cheapest_by_evaluations"] = {
        f"{t:.0e}": cheapest_at(result.rows, t, cost="vector_field_evaluations") for t in targets
    }
    record.update(extra)
    _dump_json(record, path)


def _dump_json(record: dict[str, Any], path: str | os.PathLike) -> None:
    with open(path, "w") as file:
        json.dump(record, file, indent=1, default=_json_default, allow_nan=True)


def _json_default(value):
    try:
        import numpy as np

        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, np.ndarray) or hasattr(value, "__array__"):  # JAX arrays too
            return np.asarray(value).tolist()
    except ImportError:  # pragma: no cover
        pass
    raise TypeError(f"not JSON serialisable: {value!r}")


def cheapest_at(
    rows: Iterable[dict[str, Any]], target: float, *, cost: str = "seconds", schedule: str | None = None
) -> dict[str, Any] | None:
    """The cheapest setting (by `cost`) whose error is at most `target`, or None.

    Only rows of `schedule` count (default: the first schedule in the rows).
    """
    rows = list(rows)
    if not rows:
        return None
    schedule = rows[0]["schedule"] if schedule is None else schedule
    candidates = [
        row for row in rows
        if row["schedule"] == schedule and row["solver_ok"] and not math.isnan(row["error"]) and row["error"] <= target
        and not math.isnan(row[cost])
    ]
    if not candidates:
        return None
    best = min(candidates, key=lambda row: row[cost])
    return {
        "label": best["label"], "setting": _setting(best), "error": best["error"], cost: best[cost],
        "schedule": schedule,
    }


def _setting(row: dict[str, Any]) -> str:
    if row["controller"] == "ConstantStepSize":
        return f"dt={row['dt']:.3g} ({row['substeps']} substeps)"
    return f"rtol={row['rtol']:.0e}, atol={row['atol']:.0e}"


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of the rows, for the terminal."""
    header = ("schedule", "solver", "setting", "error", "max_error", "seconds", "steps", "f-evals", "energy drift")
    lines = [header]
    for row in rows:
        lines.append((
            row["schedule"], row["label"], _setting(row), f"{row['error']:.2e}", f"{row['max_error']:.2e}",
            f"{row['seconds']:.2e}", f"{row['steps']:.0f}",
            "" if math.isnan(row["vector_field_evaluations"]) else f"{row['vector_field_evaluations']:.0f}",
            "" if math.isnan(row.get("energy_drift", math.nan)) else f"{row['energy_drift']:.2e}",
        ))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)


def format_orders(orders: Sequence[dict[str, Any]]) -> str:
    lines = []
    for entry in orders:
        parts = [f"{entry['schedule']:>9} {entry['solver']:<9} order {entry['order']:.2f} ({entry['points']} points)"]
        for name in ("energy_drift_order", "momentum_drift_order"):
            if name in entry:
                parts.append(f"{name.replace('_order', '').replace('_', ' ')} order {entry[name]:.2f}")
        lines.append(", ".join(parts))
    return "\n".join(lines)


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as error:
        raise ImportError("plots need matplotlib: pip install 'lerax_like[study]'") from error
    return plt


def plot_work_precision(
    rows: Sequence[dict[str, Any]], path: str | os.PathLike | None = None, *, schedule: str | None = None,
    title: str | None = None,
):
    """Work-precision diagram: error against run time and against vector-field evaluations.

    One line per solver (fixed-step lines swept over substeps, adaptive ones over
    tolerances), for one schedule (default: the first). Returns the figure; saves it
    as PNG when `path` is given.
    """
    plt = _pyplot()
    schedule = rows[0]["schedule"] if schedule is None else schedule
    selected = [row for row in rows if row["schedule"] == schedule and row["solver_ok"]]
    labels = list(dict.fromkeys(row["label"] for row in selected))
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for label in labels:
        line = [row for row in selected if row["label"] == label]
        adaptive = line[0]["controller"] != "ConstantStepSize"
        style = dict(marker="s" if adaptive else "o", linestyle="--" if adaptive else "-", label=label)
        axes[0].loglog([r["error"] for r in line], [r["seconds"] for r in line], **style)
        if not any(math.isnan(r["vector_field_evaluations"]) for r in line):
            axes[1].loglog([r["error"] for r in line], [r["vector_field_evaluations"] for r in line], **style)
    batch, horizon = selected[0]["batch"], selected[0]["horizon"]
    axes[0].set_ylabel(f"seconds (batch of {batch}, min of repeats)")
    axes[1].set_ylabel("vector-field evaluations per trajectory")
    for axis in axes:
        axis.set_xlabel("max-norm error at final time vs SciPy reference")
        axis.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize="small")
    scene = selected[0]["scene"]
    title = title or f"{scene}: work-precision, {schedule} actions, {horizon} env steps of {selected[0]['env_dt']:g} s"
    return _finish(plt, figure, title, path)


def _finish(plt, figure, title: str, path: str | os.PathLike | None):
    """Title and lay out `figure`; save it as PNG (and release it) when `path` is given."""
    figure.suptitle(title)
    figure.tight_layout()
    if path is not None:
        figure.savefig(path, dpi=110)
        plt.close(figure)
    return figure


def write_study(result: StudyResult, out: str | os.PathLike, *, plot: bool = True, **extra) -> dict[str, str]:
    """Write `<scene>.csv`, `<scene>.json` and (if `plot`) `<scene>.png` into `out`."""
    os.makedirs(out, exist_ok=True)
    stem = os.path.join(out, result.config.scene)
    paths = {"csv": stem + ".csv", "json": stem + ".json"}
    write_csv(result.rows, paths["csv"])
    write_json(result, paths["json"], **extra)
    if plot:
        paths["png"] = stem + ".png"
        plot_work_precision(result.rows, paths["png"])
    return paths


def format_gradient_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of a gradient study's rows, for the terminal."""
    header = ("solver", "setting", "gradient error", "seconds", "solver ok")
    lines = [header]
    for row in rows:
        lines.append((row["label"], _setting(row), f"{row['error']:.2e}", f"{row['seconds']:.2e}", str(row["solver_ok"])))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)


def plot_gradient_work_precision(
    rows: Sequence[dict[str, Any]], path: str | os.PathLike | None = None, *,
    signs: dict[str, Any] | None = None, title: str | None = None,
):
    """Gradient error against the solver's step and against the time of one gradient.

    Left: fixed-step lines against their step, adaptive ones (dashed) against `rtol`;
    right: against the run time. With `signs` (from `sensitivity_signs`), a middle panel
    shows the sensitivity of the env's own solver against the reference's along the
    trajectory. Returns the figure; saves it as PNG when `path` is given.
    """
    plt = _pyplot()
    selected = [row for row in rows if row["solver_ok"]]
    if not selected:
        raise ValueError("no row with a successful solve to plot")
    figure, axes = plt.subplots(1, 3 if signs else 2, figsize=(15 if signs else 10.5, 4.3))
    by_step, by_time = axes[0], axes[-1]
    for label in dict.fromkeys(row["label"] for row in selected):
        line = [row for row in selected if row["label"] == label]
        errors = [max(row["error"], 1e-16) for row in line]  # an exact zero has no logarithm
        adaptive = line[0]["controller"] != "ConstantStepSize"
        style = dict(marker="s" if adaptive else "o", linestyle="--" if adaptive else "-")
        steps = [row["rtol"] if adaptive else row["dt"] for row in line]
        by_step.loglog(steps, errors, label=f"{label} (x: rtol)" if adaptive else label, **style)
        by_time.loglog([row["seconds"] for row in line], errors, label=label, **style)
    reference = f"reference (Dopri8, rtol {selected[0]['reference_rtol']:g})"
    by_step.set_xlabel("solver step (s); rtol for adaptive (dashed)")
    by_step.set_ylabel(f"relative gradient error vs {reference}")
    by_step.set_title("gradient error per solver and step")
    by_time.set_xlabel(f"seconds per gradient ({selected[0]['mode']} mode, median)")
    by_time.set_title("gradient work-precision")
    for axis in (by_step, by_time):
        axis.grid(True, which="major", alpha=0.3)
        axis.legend(fontsize="small")
    if signs:
        middle = axes[1]
        middle.plot(signs["times"], signs["reference"], label="continuous (reference)")
        middle.plot(signs["times"], signs["sensitivity"], label=signs.get("label", "env's solver"))
        middle.axhline(0, color="k", lw=0.5)
        step = signs["first_clear_wrong_sign_step"]
        if step is not None:
            middle.axvline(signs["times"][step], color="r", ls=":", label=f"wrong sign at t = {signs['times'][step]:.2f} s")
        middle.set_xlabel("t (s)")
        middle.set_ylabel(signs.get("quantity", "sensitivity"))
        middle.set_title("sensitivity along the trajectory")
        middle.legend(fontsize="small")
    first = selected[0]
    title = title or f"{first['scene']}: gradient work-precision, {first['horizon']} env steps of {first['env_dt']:g} s"
    return _finish(plt, figure, title, path)


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
    _dump_json({**record, **extra}, paths["json"])
    if plot:
        paths["png"] = stem + ".png"
        plot_gradient_work_precision(result.rows, paths["png"], signs=signs)
    return paths
