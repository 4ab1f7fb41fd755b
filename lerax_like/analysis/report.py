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
    "scene", "schedule", "solver", "label", "order", "controller", "dt", "env_dt", "substeps", "rtol", "atol",
    "error", "max_error", "l2_error", "linf_error", "seconds", "seconds_spread", "timing_floor",
    "steps", "attempted_steps", "rejected_steps", "vector_field_evaluations",
    "energy_drift", "momentum_drift", "solver_ok", "batch", "horizon", "dtype",
    "reference_method", "reference_tolerance", "reference_floor", "dense_points",
)
"""One row per schedule and solver setting. `solver` is the solver's name (a preset's, or
its class name) and `order` the method's order (empty if unknown). `error` is the
max-norm error at the final time, `max_error` over the env-step ends; `l2_error` (root
mean square) and `linf_error` (maximum) are over a dense grid of `dense_points` per env
step including its end, from the solver's own dense output against SciPy's (as
DiffEqDevTools' `L2` and `Linf`); all maximal over the batch. `seconds` is the minimum
over repeats of the whole batch's run, `seconds_spread` (median - min) / min over the
repeats, `timing_floor` the time of an empty compiled call; `steps` accepted,
`rejected_steps` rejected solver steps and `vector_field_evaluations` per trajectory;
`dt` the solver's step (fixed-step rows)."""


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
        "dt", "env_dt", "rtol", "atol", "order", "error", "max_error", "l2_error", "linf_error", "seconds",
        "seconds_spread", "timing_floor", "steps", "attempted_steps", "rejected_steps",
        "vector_field_evaluations", "energy_drift", "momentum_drift", "reference_tolerance", "reference_floor",
    }
    rows = []
    with open(path, newline="") as file:
        for raw in csv.DictReader(file):
            row: dict[str, Any] = dict(raw)
            for key in numeric & raw.keys():
                row[key] = float(raw[key]) if raw[key] != "" else math.nan
            for key in ("substeps", "batch", "horizon", "dense_points"):
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
    header = (
        "schedule", "solver", "setting", "error", "max_error", "linf_error", "l2_error", "seconds",
        "steps (rejected)", "f-evals", "energy drift",
    )
    lines = [header]
    for row in rows:
        seconds = f"{row['seconds']:.2e}"
        if _timing_unresolved(row):
            seconds += "~"
        lines.append((
            row["schedule"], row["label"], _setting(row), f"{row['error']:.2e}", f"{row['max_error']:.2e}",
            f"{row.get('linf_error', math.nan):.2e}", f"{row.get('l2_error', math.nan):.2e}", seconds,
            f"{row['steps']:.0f} ({row.get('rejected_steps', 0.0):.0f})",
            "" if math.isnan(row["vector_field_evaluations"]) else f"{row['vector_field_evaluations']:.0f}",
            "" if math.isnan(row.get("energy_drift", math.nan)) else f"{row['energy_drift']:.2e}",
        ))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    table = "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)
    if any(_timing_unresolved(row) for row in rows):
        table += (
            f"\n~ timing not resolved: within {UNRESOLVED_TIMING_FACTOR:g}x of an empty compiled call, or repeats "
            f"differing by more than {UNRESOLVED_SPREAD:.0%}; compare f-evals instead"
        )
    return table


UNRESOLVED_TIMING_FACTOR = 3.0
UNRESOLVED_SPREAD = 0.25


def _timing_unresolved(row: dict[str, Any]) -> bool:
    """Whether a row's time says little: near the cost of an empty call, or noisy repeats."""
    floor = row.get("timing_floor", math.nan)
    spread = row.get("seconds_spread", math.nan)
    return bool(
        (not math.isnan(floor) and row["seconds"] < UNRESOLVED_TIMING_FACTOR * floor)
        or (not math.isnan(spread) and spread > UNRESOLVED_SPREAD)
    )


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
        parts = [f"{head} order {entry['order']:.2f} ({entry['points']} points){expected}"]
        for name in ("energy_drift_order", "momentum_drift_order"):
            if name in entry and entry[name] is not None and not math.isnan(entry[name]):
                parts.append(f"{name.replace('_order', '').replace('_', ' ')} order {entry[name]:.2f}")
        lines.append(", ".join(parts))
    return "\n".join(lines)


PLOT_HINT = "pip install 'lerax_like[study]' (or pip install matplotlib)"


def _pyplot():
    try:
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
    except ImportError as error:
        raise ImportError(f"plots need matplotlib: {PLOT_HINT}") from error
    return plt


def matplotlib_available() -> bool:
    """Whether matplotlib can be imported (plots are optional)."""
    try:
        _pyplot()
    except ImportError:
        return False
    return True


def _point_label(row: dict[str, Any]) -> str:
    if row["controller"] == "ConstantStepSize":
        return f"h={row['dt']:.2g}"
    return f"{row['rtol']:.0e}".replace("e-0", "e-")


def _slope_triangle(axis, x, y, order: float, color, *, below: bool = True) -> None:
    """An order guide: a right triangle of slope `order` in log-log axes, at `(x, y)`."""
    x1 = 2.0 * x
    y1 = y * 2.0**order
    corner = (x1, y) if below else (x, y1)
    axis.plot([x, x1, corner[0], x], [y, y1, corner[1], y], color=color, lw=0.9, alpha=0.8)
    tx = x1 * 1.08 if below else x / 1.08
    axis.text(tx, (y * y1) ** 0.5, f"{order:g}", color=color, fontsize=8, va="center",
              ha="left" if below else "right")


def _order_guides(axis, line: list[dict[str, Any]], key: str, floor: float, ceiling: float, color) -> None:
    """A slope triangle of the method's order under the part of `line` in the fitting window."""
    order = line[0].get("order", math.nan)
    if order is None or math.isnan(order):
        return
    points = [(r["dt"], r[key]) for r in line if floor < r[key] < ceiling and math.isfinite(r[key])]
    if len(points) < 2:
        return
    points.sort()
    x, y = points[len(points) // 2 - 1] if len(points) > 2 else points[0]
    _slope_triangle(axis, x, y / 6.0, order, color)


def plot_work_precision(
    rows: Sequence[dict[str, Any]], path: str | os.PathLike | None = None, *, schedule: str | None = None,
    title: str | None = None, fit_ceiling: float = 1e-2,
):
    """The work-precision figure of a study, for one schedule (default: the first).

    Panels: error at the final time against vector-field evaluations per trajectory
    (attempted solver steps where an implicit solver's evaluations are unknown), and
    against run time (hollow markers: timing not resolved); for fixed-step solvers, error
    against step size with order guides (slope triangles of each method's order); with a
    zero-force schedule, energy drift against step size. The reference floor is drawn on
    every error axis, each point is labelled by its step `h` or `rtol`, and one legend
    serves the figure. Returns the figure; saves it as PNG when `path` is given. The
    legend's labels are in `figure.legend_labels`.
    """
    plt = _pyplot()
    schedule = rows[0]["schedule"] if schedule is None else schedule
    selected = [row for row in rows if row["schedule"] == schedule and row["solver_ok"]]
    if not selected:
        raise ValueError(f"no row of schedule {schedule!r} with a successful solve to plot")
    zero = [row for row in rows if row["schedule"] == "zero" and row["solver_ok"]
            and row["controller"] == "ConstantStepSize" and not math.isnan(row.get("energy_drift", math.nan))]
    labels = list(dict.fromkeys(row["label"] for row in selected))
    fixed = {row["label"] for row in selected if row["controller"] == "ConstantStepSize"}
    by_evaluations = all(not math.isnan(row["vector_field_evaluations"]) for row in selected)
    panels = ["cost", "time"]
    if fixed:
        panels.append("step")
    if zero:
        panels.append("drift")
    if not fixed and not zero:
        panels.append("steps")
    columns = 3 if len(panels) == 3 else 2
    rows_of_panels = (len(panels) + columns - 1) // columns
    figure, axes = plt.subplots(
        rows_of_panels, columns, figsize=(6 * columns, 4.6 * rows_of_panels + 0.8), squeeze=False
    )
    axes_by_panel = dict(zip(panels, axes.flat))
    for unused in list(axes.flat)[len(panels):]:
        unused.set_visible(False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    solver_names = list(dict.fromkeys(row["solver"] for row in selected + zero))
    color_of = {name: colors[i % len(colors)] for i, name in enumerate(solver_names)}
    floor = max(row["reference_floor"] for row in selected)
    handles = {}
    labelled: list[tuple] = []  # (log10 x, log10 y, annotation, first text, series) of each label placed

    for label in labels:
        line = [row for row in selected if row["label"] == label]
        adaptive = line[0]["controller"] != "ConstantStepSize"
        color = color_of[line[0]["solver"]]
        style = dict(marker="s" if adaptive else "o", linestyle="--" if adaptive else "-", color=color, ms=4.5, lw=1.3)
        errors = [max(row["error"], 1e-17) for row in line]  # an exact zero has no logarithm
        cost_axis = axes_by_panel["cost"]
        cost = [row["vector_field_evaluations"] if by_evaluations else row["attempted_steps"] for row in line]
        (handle,) = cost_axis.loglog(errors, cost, **style)
        handles[label] = handle
        for row, x, y in zip(line, errors, cost):
            # A label that would print over another (Heun's and the midpoint rule's steps
            # sit on top of each other; dopri8's tolerances stack at the floor) is left to the first,
            # which names the stack of one solver's settings ("1e-4..1e-12").
            text, u, v = _point_label(row), math.log10(x), math.log10(y)
            near = next((entry for entry in labelled if abs(u - entry[0]) < 0.4 and abs(v - entry[1]) < 0.12), None)
            if near is None:
                annotation = cost_axis.annotate(text, (x, y), xytext=(3, 3), textcoords="offset points",
                                                fontsize=6, color=color, alpha=0.9)
                labelled.append((u, v, annotation, text, label))
            elif text != near[3] and label == near[4]:
                near[2].set_text(f"{near[3]}..{text}")
        time_axis = axes_by_panel["time"]
        time_axis.loglog(errors, [row["seconds"] for row in line], **style)
        unresolved = [(x, row["seconds"]) for row, x in zip(line, errors) if _timing_unresolved(row)]
        if unresolved:
            time_axis.plot(*zip(*unresolved), linestyle="none", marker=style["marker"], ms=7, mfc="white",
                           mec=color, zorder=3)
        if not adaptive and "step" in axes_by_panel:
            step_axis = axes_by_panel["step"]
            step_axis.loglog([row["dt"] for row in line], errors, **style)
            _order_guides(step_axis, [dict(r, error=e) for r, e in zip(line, errors)], "error", 10 * floor,
                          fit_ceiling, color)
        if adaptive and "steps" in axes_by_panel:
            steps_axis = axes_by_panel["steps"]
            rtols = [row["rtol"] for row in line]
            steps_axis.loglog(rtols, [row["steps"] for row in line], **style)
            rejected = [max(row.get("rejected_steps", 0.0), 0.5) for row in line]
            steps_axis.loglog(rtols, rejected, marker=style["marker"], linestyle=":", color=color, ms=4, mfc="white")

    if "drift" in axes_by_panel:
        drift_axis = axes_by_panel["drift"]
        for label in dict.fromkeys(row["label"] for row in zero):
            line = [row for row in zero if row["label"] == label]
            color = color_of[line[0]["solver"]]
            (handle,) = drift_axis.loglog([row["dt"] for row in line], [max(row["energy_drift"], 1e-17) for row in line],
                                          marker="o", linestyle="-", color=color, ms=4.5, lw=1.3)
            handles.setdefault(label, handle)
            _order_guides(drift_axis, line, "energy_drift", 1e-13, fit_ceiling, color)
        drift_axis.set_xlabel("solver step h (s)")
        drift_axis.set_ylabel("max |energy(t) - energy(0)|")
        drift_axis.set_title("energy drift, zero force (fixed steps; triangles: method order)", fontsize=10)

    batch, horizon = selected[0]["batch"], selected[0]["horizon"]
    error_label = "max-norm error at final time vs SciPy reference"
    cost_axis = axes_by_panel["cost"]
    cost_axis.set_ylabel("vector-field evaluations per trajectory" if by_evaluations
                         else "solver steps per trajectory (accepted + rejected)")
    cost_axis.set_title("work-precision: evaluations (labels: step h or rtol)" if by_evaluations
                        else "work-precision: solver steps (implicit: evaluations depend on Newton)", fontsize=10)
    time_axis = axes_by_panel["time"]
    time_axis.set_ylabel(f"seconds, batch of {batch} (min of repeats)")
    time_axis.set_title("work-precision: run time (hollow: timing not resolved)", fontsize=10)
    smallest = min(max(row["error"], 1e-17) for row in selected)
    low = min(smallest, floor) / 4
    for axis in (cost_axis, time_axis):
        axis.set_xlabel(error_label)
        axis.set_xlim(low, axis.get_xlim()[1])
        axis.axvspan(low, floor, color="0.85", alpha=0.6, lw=0)
        axis.axvline(floor, color="0.4", lw=1, ls=":")
        axis.text(floor, 0.02, " reference floor", transform=axis.get_xaxis_transform(), fontsize=7, color="0.3",
                  rotation=90, va="bottom", ha="right")
    if "step" in axes_by_panel:
        step_axis = axes_by_panel["step"]
        step_axis.set_ylim(low, step_axis.get_ylim()[1])
        step_axis.axhspan(low, floor, color="0.85", alpha=0.6, lw=0)
        step_axis.axhline(floor, color="0.4", lw=1, ls=":")
        step_axis.text(0.02, floor, "reference floor", transform=step_axis.get_yaxis_transform(), fontsize=7,
                       color="0.3", va="bottom")
        step_axis.set_xlabel("solver step h (s)")
        step_axis.set_ylabel(error_label)
        step_axis.set_title("convergence, fixed steps (triangles: method order)", fontsize=10)
    if "steps" in axes_by_panel:
        steps_axis = axes_by_panel["steps"]
        steps_axis.set_xlabel("rtol (atol = rtol / 1000)")
        steps_axis.set_ylabel("solver steps per trajectory")
        steps_axis.set_title("accepted (filled) and rejected (hollow, dotted) steps", fontsize=10)
    for axis in axes_by_panel.values():
        axis.grid(True, which="major", alpha=0.3)
    legend_labels = list(handles)
    figure.legend(list(handles.values()), legend_labels, loc="lower center", ncol=min(len(handles), 6),
                  fontsize="small", frameon=False)
    figure.legend_labels = legend_labels
    scene = selected[0]["scene"]
    title = title or f"{scene}: work-precision, {schedule} actions, {horizon} env steps of {selected[0]['env_dt']:g} s"
    figure.suptitle(title)
    legend_rows = (len(handles) + 5) // 6
    figure.tight_layout(rect=(0, 0.035 * legend_rows + 0.02, 1, 1))
    if path is not None:
        figure.savefig(path, dpi=110)
        plt.close(figure)
    return figure


def _finish(plt, figure, title: str, path: str | os.PathLike | None):
    """Title and lay out `figure`; save it as PNG (and release it) when `path` is given."""
    figure.suptitle(title)
    figure.tight_layout()
    if path is not None:
        figure.savefig(path, dpi=110)
        plt.close(figure)
    return figure


def write_study(
    result: StudyResult, out: str | os.PathLike, *, plot: bool = True, stem: str | None = None,
    title: str | None = None, **extra,
) -> dict[str, str]:
    """Write `<stem>.csv`, `<stem>.json` and (if `plot`) `<stem>.png` into `out` (stem: the scene).

    Without matplotlib the plot is skipped, not an error: `paths` then has no `"png"`
    and the JSON says `"figure": {"skipped": ...}`. The JSON records the legend's labels.
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
            figure_record = {"path": os.path.basename(paths["png"]), "legend": figure.legend_labels}
        else:
            figure_record = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    write_json(result, paths["json"], figure=figure_record, **extra)
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
    if plot and matplotlib_available():
        paths["png"] = stem + ".png"
        plot_gradient_work_precision(result.rows, paths["png"], signs=signs)
    elif plot:
        record["figure"] = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    _dump_json({**record, **extra}, paths["json"])
    return paths
