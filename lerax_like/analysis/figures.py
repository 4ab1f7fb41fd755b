"""The figures of the work-precision studies: of the solutions and of their gradients.

Drawn from a study's rows alone (as read back by `study.read_csv` too), with matplotlib,
an optional dependency (`recording.pyplot` raises with the install hint).
"""

import math
import os
import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..gradients import ESTIMATORS
from .recording import finish_figure, pyplot, save_figure
from .verdict import group_settings, timing_unresolved


# One per preset, in `SOLVERS.names` order (euler, heun, midpoint, ralston, rk4, tsit5, dopri5,
# dopri8, implicit_euler, kvaerno3, kvaerno4, kvaerno5, semi_implicit_euler): matplotlib's
# colours as the studies drew them before (rk4 red, tsit5 purple, ...), no grey (the
# reference floor's and the failed markers'), then darker ones.
_PRESET_COLOURS = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#bcbd22", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf",
    "#393b79", "#637939", "#843c39", "#000000",
)
# Any other solver (a user's): one of these, by a hash of its name that does not change between runs.
_OTHER_COLOURS = ("#5254a3", "#8ca252", "#bd9e39", "#ad494a", "#a55194", "#6b6ecf", "#b5cf6b", "#e7ba52")


def solver_colour(name: str) -> str:
    """The colour of a solver in every figure: fixed by its name, whatever else is plotted.

    A preset's by its place among the presets; another solver's (`Kutta3`, `Bosh3#2`) by a
    hash of its name (CRC-32, stable between runs, unlike Python's `hash`).
    """
    from ..integrate import SOLVERS

    presets = list(SOLVERS.names)
    if name in presets and presets.index(name) < len(_PRESET_COLOURS):
        return _PRESET_COLOURS[presets.index(name)]
    return _OTHER_COLOURS[zlib.crc32(name.encode()) % len(_OTHER_COLOURS)]


def _tidy_log_ticks(axis) -> None:
    """Label a log axis at its decades only, or at 1, 2 and 5 times them where it spans
    less than two decades: matplotlib otherwise labels every minor tick of a short axis,
    and the labels run into each other."""
    from matplotlib.ticker import LogLocator, NullFormatter

    for which, (low, high) in (("x", axis.get_xlim()), ("y", axis.get_ylim())):
        if getattr(axis, f"get_{which}scale")() != "log" or not (low > 0 and high > 0):
            continue
        ticks = getattr(axis, f"{which}axis")
        if abs(math.log10(high / low)) < 2:
            ticks.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        ticks.set_minor_formatter(NullFormatter())


def _place_labels(figure, candidates) -> None:
    """Annotate points, leaving out a label that would overlap one already placed.

    `candidates` are `(axis, x, y, text, colour, series)` in drawing order. Drawn after the
    layout, from the labels' real extents: the first label of a stack stays, and where the
    stack is one series' settings (Dopri8's tolerances all at the floor), it names their
    range ("1e-4..1e-12"); another series' label over it is left out (its point and colour
    stay, and the legend names it).
    """
    renderer = figure.canvas.get_renderer()
    placed = []  # (axis, extent, annotation, first text, series)
    for axis, x, y, text, colour, series in candidates:
        annotation = axis.annotate(text, (x, y), xytext=(3, 3), textcoords="offset points", fontsize=6,
                                   color=colour, alpha=0.9)
        extent = annotation.get_window_extent(renderer).expanded(1.05, 1.15)
        clash = next((entry for entry in placed if entry[0] is axis and entry[1].overlaps(extent)), None)
        if clash is None:
            placed.append((axis, extent, annotation, text, series))
            continue
        annotation.remove()
        first, last = clash[3].split("..")[0], text.split("..")[-1]
        if clash[4] == series and last != first:
            clash[2].set_text(f"{first}..{last}")


def _point_label(row: dict[str, Any]) -> str:
    if row["controller"] == "ConstantStepSize":
        return f"h={row['dt']:.2g}"
    if row.get("members", 1) > 1:  # a group of tolerances: "1e-4..1e-12"
        return row["setting"].split(",")[0].removeprefix("rtol=").replace("e-0", "e-")
    return f"{row['rtol']:.0e}".replace("e-0", "e-")


def order_guide(points, order: float) -> tuple[float, float, float, float] | None:
    """Where an order guide (a right triangle of slope `order` in log-log axes) goes:
    `(x0, x1, y0, y1)`, inside the box that `points` (`(step, error)` pairs of one line)
    span.

    It is at most half the line's span in each direction and at most a factor 2 wide,
    centred on the line's steps and just below the line, so that a short sweep (the
    quick study's three steps) gets a small triangle instead of one larger than its
    data. None for fewer than two distinct points or no order.
    """
    points = sorted((x, y) for x, y in points if x > 0 and y > 0 and math.isfinite(x) and math.isfinite(y))
    if order is None or not math.isfinite(order) or order <= 0 or len(points) < 2:
        return None
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    span_x, span_y = math.log(xs[-1] / xs[0]), math.log(max(ys) / min(ys))
    if span_x <= 0 or span_y <= 0:
        return None
    log_width = min(math.log(2.0), span_x / 2, span_y / (2 * order))
    x0 = math.exp(0.5 * (math.log(xs[0]) + math.log(xs[-1])) - log_width / 2)
    x1 = x0 * math.exp(log_width)
    # The line at x0, interpolated in log-log between its neighbours.
    right = next(i for i, x in enumerate(xs) if x >= x0)
    left = max(right - 1, 0)
    if xs[right] == xs[left]:
        at_x0 = ys[right]
    else:
        share = (math.log(x0) - math.log(xs[left])) / (math.log(xs[right]) - math.log(xs[left]))
        at_x0 = math.exp(math.log(ys[left]) + share * (math.log(ys[right]) - math.log(ys[left])))
    height = math.exp(order * log_width)
    y0 = max(at_x0 / math.exp(min(math.log(6.0), span_y / 4)), min(ys))
    y0 = min(y0, max(ys) / height)
    return x0, x1, y0, y0 * height


def _order_guides(axis, line: list[dict[str, Any]], key: str, floor: float, ceiling: float, color) -> None:
    """An order guide of the method's order beside the part of `line` in the fitting window."""
    order = line[0].get("order", math.nan)
    points = [(r["dt"], r[key]) for r in line if floor < r[key] < ceiling and math.isfinite(r[key])]
    guide = order_guide(points, order)
    if guide is None:
        return
    x0, x1, y0, y1 = guide
    axis.plot([x0, x1, x1, x0], [y0, y1, y0, y0], color=color, lw=0.9, alpha=0.8)
    axis.text(x1 * 1.05, (y0 * y1) ** 0.5, f"{order:g}", color=color, fontsize=8, va="center", ha="left")


def plot_work_precision(
    rows: Sequence[dict[str, Any]], path: str | os.PathLike | None = None, *, schedule: str | None = None,
    title: str | None = None, fit_ceiling: float = 1e-2,
):
    """The work-precision figure of a study, for one schedule (default: the first).

    Panels: error at the final time against vector-field evaluations per trajectory
    (attempted solver steps where an implicit solver's evaluations are unknown), and
    against run time (hollow markers: timing not resolved, as `verdict.timing_unresolved`
    and the table mark it); for fixed-step solvers, error against step size with order
    guides (slope triangles of each method's order, inside the data: `order_guide`); with a
    zero-force schedule, energy drift against step size. The reference floor is drawn on
    every error axis, each point is labelled by its step `h` or `rtol`, and one legend
    serves the figure. Settings whose errors and step counts coincide are one point
    (`verdict.group_settings`). Returns the figure; saves it as PNG when `path` is given. The
    legend's labels are in `figure.legend_labels`.
    """
    plt = pyplot()
    schedule = rows[0]["schedule"] if schedule is None else schedule
    # Settings whose errors and steps coincide are one point (their labels name the range).
    selected = group_settings(row for row in rows if row["schedule"] == schedule and row["solver_ok"])
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
    floor = max(row["reference_floor"] for row in selected)
    handles = {}
    labels_to_place: list[tuple] = []  # (axis, x, y, text, colour, series), placed after the layout

    for label in labels:
        line = [row for row in selected if row["label"] == label]
        adaptive = line[0]["controller"] != "ConstantStepSize"
        color = solver_colour(line[0]["solver"])
        style = dict(marker="s" if adaptive else "o", linestyle="--" if adaptive else "-", color=color, ms=4.5, lw=1.3)
        errors = [max(row["error"], 1e-17) for row in line]  # an exact zero has no logarithm
        cost_axis = axes_by_panel["cost"]
        cost = [row["vector_field_evaluations"] if by_evaluations else row["attempted_steps"] for row in line]
        (handle,) = cost_axis.loglog(errors, cost, **style)
        handles[label] = handle
        labels_to_place += [(cost_axis, x, y, _point_label(row), color, label) for row, x, y in zip(line, errors, cost)]
        time_axis = axes_by_panel["time"]
        time_axis.loglog(errors, [row["seconds"] for row in line], **style)
        unresolved = [(x, row["seconds"]) for row, x in zip(line, errors) if timing_unresolved(row)]
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
            color = solver_colour(line[0]["solver"])
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
    failed = group_settings(row for row in rows if row["schedule"] == schedule and not row["solver_ok"])
    if failed:
        # No error to place them by: at the right edge of the cost panel, at their cost.
        edge = cost_axis.get_yaxis_transform()  # x in axes coordinates, y in data
        for row in failed:
            cost = row["vector_field_evaluations"] if by_evaluations else row["attempted_steps"]
            if not (math.isfinite(cost) and cost > 0):
                cost = row["attempted_steps"]
            (marker,) = cost_axis.plot([1.0], [max(cost, 1.0)], transform=edge, marker="X", ms=8, linestyle="none",
                                       color=solver_colour(row["solver"]), clip_on=False, zorder=4)
            marker.set_gid("failed")
        handles["failed (right edge; why below)"] = cost_axis.plot([], [], marker="X", linestyle="none", color="0.3")[0]
    if "steps" in axes_by_panel:
        steps_axis = axes_by_panel["steps"]
        steps_axis.set_xlabel("rtol (atol = rtol / 1000)")
        steps_axis.set_ylabel("solver steps per trajectory")
        steps_axis.set_title("accepted (filled) and rejected (hollow, dotted) steps", fontsize=10)
    for axis in axes_by_panel.values():
        axis.grid(True, which="major", alpha=0.3)
        _tidy_log_ticks(axis)
    failed_settings = [
        {"label": row["label"], "setting": row["setting"], "failure": row.get("failure") or "unknown"} for row in failed
    ]
    setattr(figure, "failed_settings", failed_settings)  # an attribute of our own on matplotlib's Figure
    notes = [f"failed: {f['label']} at {f['setting']}: {f['failure']}" for f in failed_settings]
    # The notes under the legend: a line of 7-point text is about 10 points of the figure's height.
    notes_height = (len(notes) * 10 / (72 * figure.get_figheight()) + 0.01) if notes else 0.0
    if notes:
        figure.text(0.01, 0.005, "\n".join(notes), fontsize=7, color="0.2", va="bottom", ha="left")
    legend_labels = list(handles)
    figure.legend(list(handles.values()), legend_labels, loc="lower center", ncol=min(len(handles), 6),
                  fontsize="small", frameon=False, bbox_to_anchor=(0.5, notes_height))
    setattr(figure, "legend_labels", legend_labels)  # an attribute of our own on matplotlib's Figure
    scene = selected[0]["scene"]
    title = title or f"{scene}: work-precision, {schedule} actions, {horizon} env steps of {selected[0]['env_dt']:g} s"
    figure.suptitle(title)
    legend_rows = (len(handles) + 5) // 6
    figure.tight_layout(rect=(0, 0.035 * legend_rows + 0.02 + notes_height, 1, 1))
    _place_labels(figure, labels_to_place)
    return save_figure(figure, path)


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
    plt = pyplot()
    selected = [row for row in rows if row["solver_ok"]]
    if not selected:
        raise ValueError("no row with a successful solve to plot")
    figure, axes = plt.subplots(1, 3 if signs else 2, figsize=(15 if signs else 10.5, 4.3))
    by_step, by_time = axes[0], axes[-1]
    for label in dict.fromkeys(row["label"] for row in selected):
        line = [row for row in selected if row["label"] == label]
        errors = [max(row["error"], 1e-16) for row in line]  # an exact zero has no logarithm
        adaptive = line[0]["controller"] != "ConstantStepSize"
        style = dict(marker="s" if adaptive else "o", linestyle="--" if adaptive else "-",
                     color=solver_colour(line[0]["solver"]))
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
    return finish_figure(figure, title, path)


def plot_gradient_variance(result, path=None):
    """Variance and bias against horizon, one line per estimator and solver; float32 error.

    One row of panels per policy and sigma: the variance (log) with the first-order
    variance the Lyapunov exponent predicts (dotted); the bias with its standard error
    (the band noise alone gives); the relative error of the float32 gradient against
    float64 at the nominal `theta`, where the study measured it (`config.precision`).
    `result` is what `run_gradient_variance` returns.
    Returns the figure; saves it when `path` is given.
    """
    plt = pyplot()
    config = result.config
    panels = [(kind, sigma) for kind in config.policies for sigma in config.sigmas]
    columns = 3 if config.precision else 2
    figure, axes = plt.subplots(len(panels), columns, figsize=(5 * columns, 3.6 * len(panels)), squeeze=False)
    colours = {"first_order": "C0", "zeroth_order": "C1", "alpha_order": "C2"}
    styles = ["-", "--", ":", "-."]
    dt = result.record["dt"]
    for (kind, sigma), (variance_axis, bias_axis, *precision) in zip(panels, axes):
        precision_axis = precision[0] if precision else None
        for s, solver in enumerate(config.solvers):
            style = styles[s % len(styles)]
            for name in reversed(ESTIMATORS):  # first order on top: alpha order often equals it
                line = sorted((r for r in result.rows if r["solver"] == solver and r["policy"] == kind
                               and r["sigma"] == sigma and r["estimator"] == name), key=lambda r: r["horizon"])
                h = [r["horizon"] for r in line]
                variance_axis.errorbar(h, [r["variance"] for r in line], yerr=[r["variance_standard_error"] for r in line],
                                       color=colours[name], linestyle=style, marker="o", ms=3, label=f"{name}, {solver}")
                bias_axis.plot(h, [r["bias"] for r in line], color=colours[name], linestyle=style, marker="o", ms=3,
                               label=f"{name}, {solver}")
                bias_axis.plot(h, [r["bias_standard_error"] for r in line], color=colours[name], linestyle=style,
                               lw=0.7, alpha=0.5)
            for c in result.record["crossover"]:
                if c["solver"] == solver and c["policy"] == kind and c["sigma"] == sigma:
                    first = sorted((r["horizon"], r["variance"]) for r in result.rows if r["solver"] == solver
                                   and r["policy"] == kind and r["sigma"] == sigma and r["estimator"] == "first_order")
                    h = np.linspace(first[0][0], first[-1][0], 50)
                    predicted = first[0][1] * np.exp(2 * c["lyapunov_exponent"] * (h - first[0][0]) * dt)
                    variance_axis.plot(h, predicted, color="k", linestyle=style, lw=0.8,
                                       label=f"exp(2 lambda t), lambda = {c['lyapunov_exponent']:.2g}/s, {solver}")
            for p in result.record["precision"]:
                if precision_axis is not None and p["solver"] == solver and p["policy"] == kind:
                    error = np.asarray(p["relative_error"])
                    precision_axis.semilogy(np.arange(1, len(error) + 1), np.maximum(error, 1e-17),
                                            linestyle=style, label=solver)
        variance_axis.set_yscale("log")
        bias_axis.set_yscale("log")
        variance_axis.set_ylabel("variance (trace of covariance)")
        bias_axis.set_ylabel("|estimate - reference| (thin: noise alone)")
        if precision_axis is not None:
            precision_axis.axhline(0.1, color="r", lw=0.6, label="leading digit lost")
            precision_axis.set_ylabel("float32 gradient, relative error")
            precision_axis.set_title(f"{kind}: float32 vs float64 at nominal theta", fontsize="medium")
        for axis in (variance_axis, bias_axis, *precision):
            axis.set_xlabel("horizon (env steps)")
        variance_axis.set_title(f"{kind}, sigma = {sigma:g}: variance", fontsize="medium")
        bias_axis.set_title(f"{kind}, sigma = {sigma:g}: bias against the reference", fontsize="medium")
        for axis in (variance_axis, bias_axis, *precision):
            axis.grid(True, which="major", alpha=0.3)
            axis.legend(fontsize="x-small")
    samples = f"N = {config.samples} samples (reference: {config.reference_samples} antithetic)"
    break_ = " " if columns == 3 else "\n"  # two columns are too narrow for one line
    title = f"{config.name}:{break_}gradient estimators over {samples}, dt = {dt:g} s, {config.dtype}"
    return finish_figure(figure, title, path)
