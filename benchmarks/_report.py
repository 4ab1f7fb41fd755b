"""RESULTS.md, written from the recorded result files only, so that no number can drift from its source.

Each benchmark's section states the command that produced its files (from `NAME.run.json`,
written by `python -m benchmarks NAME`), when, where and under what load, then its tables and
figures, computed here from the CSV and JSON files. The prose says how to read a table and
never repeats a number by hand. A file edited after its run record was written is flagged.
"""

import ast
import hashlib
import json
import math
import os
import pathlib

from benchmarks import BENCHMARKS, HERE, results_dir
from lerax_like.analysis.recording import read_csv_rows
from lerax_like.analysis.study import VERDICT_TARGETS, read_csv
from lerax_like.analysis.verdict import UNRESOLVED_SPREAD, UNRESOLVED_TIMING_FACTOR, cheapest_at


def _read_csv(folder: pathlib.Path, name: str) -> list[dict] | None:
    path = folder / name
    return read_csv_rows(path) if path.exists() else None


def _runs(folder: pathlib.Path, name: str):
    """`(header lines, rows)` of a benchmark's first run and of its second, where recorded:
    the second run's lines name its own provenance."""
    for stem, title in ((name, None), (f"{name}_second_run", "Second run")):
        rows = _read_csv(folder, f"{stem}.csv")
        if rows is not None:
            yield ([f"**{title}**: " + " ".join(provenance(folder, stem)).strip(), ""] if title else []), rows, stem


def _read_json(folder: pathlib.Path, name: str):
    path = folder / name
    return json.loads(path.read_text()) if path.exists() else None


def _table(header: list[str], rows: list[list]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return lines + [""]


def _g(value, digits: int = 3) -> str:
    """A number to `digits` significant figures ('' for a missing one)."""
    if value in (None, ""):
        return ""
    value = float(value)
    if math.isnan(value):
        return ""
    return f"{value:.{digits}g}"


def _duration(seconds) -> str:
    seconds = float(seconds)
    return f"{seconds:.3g} s" if seconds >= 1 else f"{seconds * 1e3:.3g} ms"


def _mega(value) -> str:
    return f"{float(value) / 1e6:.3g} M"


def summary_line(name: str) -> str:
    """The first line of a benchmark module's docstring, read without importing it."""
    tree = ast.parse((HERE / f"{name}.py").read_text())
    return (ast.get_docstring(tree) or "").splitlines()[0]


def provenance(folder: pathlib.Path, record_name: str) -> list[str]:
    """How the files of one run were made, from its run record; flags files changed since."""
    record = _read_json(folder, f"{record_name}.run.json")
    if record is None:
        return ["*No run record: these files predate `python -m benchmarks`.*", ""]
    load = record.get("load_average_at_start")
    versions = record.get("versions", {})
    parts = [f"`{record['command']}`", f"{record['date_utc']} UTC", record.get("machine", "")]
    if load:
        parts.append(f"load average {load[0]:g} at the start")
    if versions:
        parts.append(", ".join(f"{package} {version}" for package, version in versions.items()))
    if record.get("seconds"):
        parts.append(f"{record['seconds']:.0f} s")
    lines = ["Produced by " + "; ".join(part for part in parts if part) + "."]
    if record.get("note"):
        lines.append(record["note"])
    changed = [
        file for file, digest in record.get("files", {}).items()
        if not (folder / file).exists() or hashlib.sha256((folder / file).read_bytes()).hexdigest() != digest
    ]
    if changed:
        lines.append("**Changed since this run record** (regenerate them): " + ", ".join(f"`{file}`" for file in changed) + ".")
    return [" ".join(lines), ""]


# --- sections, one per benchmark --------------------------------------------------------------


def work_precision(folder, link):
    lines = []
    for path in sorted(folder.glob("work_precision_*.json")):
        scene = path.stem.removeprefix("work_precision_")
        data = json.loads(path.read_text())
        config = data["config"]
        lines += [f"### {scene}", ""]
        lines += [
            f"{config.get('batch', '')} initial states from `env.initial`, {config.get('horizon', '')} env steps "
            f"({data.get('horizon_seconds', '')} s); error: max-norm error of the final state against SciPy "
            f"`solve_ivp` ({data['reference']['method']}, rtol = atol = {data['reference']['rtol']:g}), "
            "worst of the batch; seconds: the whole batch under `vmap`, minimum of "
            f"{config.get('repeats', '')} runs. Study recorded {data.get('date', '')}.", "",
        ]
        if (folder / f"work_precision_{scene}.png").exists():
            lines += [f"![{scene} work-precision]({link}/work_precision_{scene}.png)", ""]
        lines += _verdicts(folder / f"work_precision_{scene}.csv")
        orders = [order for order in data.get("convergence_orders", []) if order.get("order") is not None]
        if orders:
            rows = []
            for order in orders:
                rows.append([order["schedule"], order["solver"], _g(order["order"]), order.get("points", ""),
                             _g(order.get("energy_drift_order")), _g(order.get("momentum_drift_order"))])
            lines += ["Fitted orders (slope of log error on log step):", ""]
            lines += _table(["actions", "solver", "error order", "points", "energy drift order", "momentum drift order"], rows)
    return lines


def _verdicts(path: pathlib.Path) -> list[str]:
    """The cheapest setting at each error level, reached from the study's CSV by the package's
    own rule (`lerax_like.analysis.verdict`): coinciding settings are one, evaluations decide,
    and run time counts only where it is resolved."""
    if not path.exists():
        return []
    rows = read_csv(path)
    table = []
    for target in VERDICT_TARGETS:
        cells = []
        for cost in ("vector_field_evaluations", "seconds"):
            best = cheapest_at(rows, target, cost=cost)
            if best is None:
                cells.append("none" if cost != "seconds" else "none with a resolved timing")
                continue
            amount = (f"{best[cost]:.0f} evaluations" if cost != "seconds" else f"{best[cost] * 1e3:.3g} ms")
            tied = f" (within timing noise of {', '.join(best['tied_with'])})" if best["tied_with"] else ""
            if best["unmeasured"]:
                tied += f" (not compared, evaluations unknown: {', '.join(best['unmeasured'])})"
            cells.append(f"`{best['label']}` {best['setting']}: error {_g(best['error'], 2)}, {amount}{tied}")
        table.append([f"{target:.0e}", *cells])
    return [
        "Cheapest setting that reaches each error (settings whose errors and step counts coincide are one "
        "setting, named by their range; run time only where it is resolved: more than "
        f"{UNRESOLVED_TIMING_FACTOR:g}x an empty compiled call and repeats within {UNRESOLVED_SPREAD:.0%}):", "",
    ] + _table(["error at most", "by vector-field evaluations", "by run time (resolved only)"], table)


def gradient_error(folder, link):
    data = _read_json(folder, "gradient_error.json")
    rows = _read_csv(folder, "gradient_error.csv")
    if data is None or rows is None:
        return []
    lines = [
        f"Reference: {data['reference']['solver']} at rtol {data['reference']['rtol']:g} "
        f"(its own error about {_g(data['reference']['floor'], 2)}).", "",
    ]
    if (folder / "gradient_error.png").exists():
        lines += [f"![gradient error]({link}/gradient_error.png)", ""]
    table = []
    for row in rows:
        setting = f"dt {_g(row['dt'])} ({row['substeps']} substeps)" if row["substeps"] else f"rtol {_g(row['rtol'])}"
        table.append([row["label"], setting, _g(row["error"], 2), f"{float(row['seconds']) * 1e3:.3g} ms", row["solver_ok"]])
    lines += _table(["solver", "setting", "relative gradient error", "time of one gradient", "solver ok"], table)
    orders = data.get("convergence_orders", [])
    if orders:
        lines += ["Fitted orders of the gradient error: " + ", ".join(
            f"{order['solver']} {_g(order['order'])}" for order in orders) + ".", ""]
    signs = data.get("wrong_sign")
    if signs:
        lines += [
            f"{signs.get('quantity', 'sensitivity')} under {signs.get('label', 'Euler')} against the reference, "
            f"along {len(signs['times'])} env steps: wrong sign on {100 * float(signs['wrong_sign_fraction']):.0f}% "
            "of the steps.", "",
        ]
        step = signs.get("first_clear_wrong_sign_step")
        if step is not None:
            lines[-2] = lines[-2][:-1] + (
                f"; at t = {_g(signs['times'][step])} s it is {_g(signs['sensitivity'][step])} where the "
                f"reference is {_g(signs['reference'][step])}."
            )
    return lines


def gradient_variance(folder, link):
    rows = _read_csv(folder, "gradient_variance.csv")
    if rows is None:
        return []
    lines = []
    for figure in sorted(folder.glob("gradient_variance*.png")):
        lines += [f"![{figure.stem}]({link}/{figure.name})", ""]
    first = {(r["case"], r["solver"], r["policy"], r["dtype"], r["sigma"], r["horizon"]): r
             for r in rows if r["estimator"] == "first_order"}
    zeroth = {(r["case"], r["solver"], r["policy"], r["dtype"], r["sigma"], r["horizon"]): r
              for r in rows if r["estimator"] == "zeroth_order"}
    table = []
    for key, row in first.items():
        other = zeroth.get(key)
        table.append([*key, _g(row["variance"], 2), _g(other["variance"], 2) if other else "",
                      _g(row["relative_bias"], 2), row["failed_samples"]])
    lines += ["Variance (trace of the per-sample covariance) of the first-order (autodiff) and zeroth-order "
              "(randomised smoothing) estimators, and the first-order estimator's bias relative to the "
              "reference; every column in `gradient_variance.csv`:", ""]
    return lines + _table(
        ["case", "solver", "policy", "dtype", "sigma", "horizon", "first-order variance", "zeroth-order variance",
         "first-order relative bias", "failed samples"], table,
    )


def contact_gradient_variance(folder, link):
    rows = _read_csv(folder, "contact_gradient_variance.csv")
    if rows is None:
        return []
    lines = []
    for figure in sorted(folder.glob("contact_gradient_variance*.png")):
        lines += [f"![{figure.stem}]({link}/{figure.name})", ""]
    table = [
        [r["case"], r["policy"], r["horizon"], _g(r["bias"], 3), _g(r["bias_standard_error"], 2),
         _g(float(r["bias"]) / float(r["bias_standard_error"]), 2), _g(r["reference_norm"], 3), _g(r["variance"], 2),
         r["failed_samples"]]
        for r in rows if r["estimator"] == "first_order"
    ]
    lines += ["The first-order (autodiff) estimator's bias against the antithetic zeroth-order reference, with "
              "the standard error that sampling noise alone gives it (a bias within about two standard errors "
              "is no evidence of bias); every column in `contact_gradient_variance.csv`:", ""]
    return lines + _table(
        ["case", "policy", "horizon", "bias", "standard error", "bias / standard error", "reference norm",
         "first-order variance", "failed samples"], table,
    )


def gradient_precision(folder, link):
    rows = _read_csv(folder, "gradient_precision.csv")
    if rows is None:
        return []
    horizons = list(dict.fromkeys(row["horizon"] for row in rows))
    lines = {}
    for row in rows:
        key = (row["case"], row["solver"], row["rtol"], row["atol"], row["policy"])
        cells = lines.setdefault(key, {"lost": row["first_digit_lost_horizon"], "errors": {}, "failed": []})
        cells["errors"][row["horizon"]] = _g(row["relative_error"], 2)
        if row["float32_solves_ok"] != "True":
            cells["failed"].append(row["horizon"])
    table = [[*key, *(cells["errors"].get(h, "") for h in horizons), cells["lost"] or "none",
              cells["failed"][0] if cells["failed"] else ""] for key, cells in lines.items()]
    return ["Relative error of the float32 gradient against the float64 one, by horizon (env steps):", ""] + _table(
        ["case", "solver", "rtol", "atol", "policy", *horizons, "leading digit lost at", "first float32 solve failure"],
        table,
    )


def gradient_memory(folder, link):
    data = _read_json(folder, "gradient_memory.json")
    if data is None:
        return []
    methods = list(dict.fromkeys(row["method"] for row in data["rows"]))
    table = []
    for solver in dict.fromkeys(row["solver"] for row in data["rows"]):
        cells = [solver]
        for method in methods:
            row = next(r for r in data["rows"] if r["solver"] == solver and r["method"] == method)
            size = row["temp_bytes"] / 2**20
            size = f"{size / 1024:.3g} GiB" if size >= 1024 else f"{size:.3g} MiB"
            cells.append(f"{size}, {_duration(row['seconds'])}")
        gradients = {r["grad_pole_mass"] for r in data["rows"] if r["solver"] == solver}
        spread = (max(gradients) - min(gradients)) / abs(max(gradients))
        cells.append(f"{spread:.1e}")
        table.append(cells)
    steps = data["rows"][0]["steps"]
    lines = [
        f"Gradient of a {steps}-step rollout, vmapped over {data.get('batch', 256)} envs: XLA's temporary-buffer "
        "size of the compiled gradient and the median time of 5 runs; the last column is the relative spread "
        "of dL/d pole_mass across the three methods (they compute the same gradient).", "",
    ]
    return lines + _table(["solver", *methods, "gradient spread"], table)


def _gradient_cost_bound(row) -> str:
    """What the row's own measurements say about a goal it misses (empty when it meets them all)."""
    reasons = []
    if float(row["reverse_over_floor"]) > float(row["goal_over_floor"]):
        reasons.append(f"our forward pass is already {float(row['forward_over_floor']):.3g}x the floor's")
    if float(row["reverse_over_forward"]) > 15:
        reasons.append(f"the floor's own reverse is {float(row['floor_reverse_over_forward']):.3g}x its forward")
    if float(row["reverse_temp_bytes"]) >= 2**30 * int(row["envs"]) / 1024:
        reasons.append(f"floor's memory {float(row['floor_reverse_temp_bytes']) / 2**20:.3g} MiB")
    if float(row["reverse_compile_s"]) >= 30:
        reasons.append(f"compile (the floor's: {_duration(row['floor_reverse_compile_s'])})")
    return "; ".join(reasons)


def gradient_cost(folder, link):
    rows = _read_csv(folder, "gradient_cost.csv")
    if rows is None:
        return []

    def ratio(value):
        return f"{float(value):.3g}x" if value not in (None, "") else ""

    def memory(value):
        if value in (None, ""):
            return ""
        size = float(value) / 2**20
        return f"{size / 1024:.3g} GiB" if size >= 1024 else f"{size:.3g} MiB"

    table = []
    for row in rows:
        if row.get("error"):
            table.append([row["scene"], row["solver"], "", "", "", "", "", "", "", "", "", "", row["error"]])
            continue
        jacfwd = _duration(row["jacfwd_s"]) if row.get("jacfwd_s") else (row.get("jacfwd_error") or "")
        table.append([
            row["scene"], row["solver"], _g(row["solver_steps_per_env_step"]), _duration(row["forward_s"]),
            _duration(row["reverse_s"]), jacfwd, _duration(row["floor_reverse_s"]),
            f"{ratio(row['reverse_over_floor'])} (goal {_g(row['goal_over_floor'])}x)", ratio(row["reverse_over_forward"]),
            memory(row["reverse_temp_bytes"]), _duration(row["reverse_compile_s"]),
            "yes" if row["meets_goals"] == "True" else "no", _gradient_cost_bound(row),
        ])
    first = rows[0]
    lines = [
        f"N = {first['envs']} envs from distinct resets, {first['steps']} steps, gradient with respect to "
        "`gravity`; times are the min of the repeats after compiling. *Floor*: the same vector field and "
        "solver steps in a hand-written `lax.scan`; *reverse / floor* compares the two value-and-gradient times; "
        "memory is XLA's temporary memory of the compiled gradient.", "",
    ]
    lines += _table(
        ["scene", "solver", "solver steps per env step", "forward", "reverse", "jacfwd", "floor reverse",
         "reverse / floor", "reverse / forward", "temp memory", "compile", "goals met", "what bounds a missed goal"],
        table,
    )
    pendulum = next((row for row in rows if row["scene"] == "Pendulum" and row.get("gymnax_forward_s")), None)
    if pendulum is not None:
        lines += [
            f"gymnax Pendulum-v1, same starts and actions: forward {_duration(pendulum['gymnax_forward_s'])}, "
            f"value and gradient {_duration(pendulum['gymnax_reverse_s'])}, gradient "
            f"{_g(pendulum['gymnax_gradient'])} (ours {_g(pendulum['gradient'])}).", "",
        ]
    return lines


def throughput(folder, link):
    lines = []
    for header, rows, stem in _runs(folder, "throughput"):
        lines += header
        counts = sorted({int(row["num_envs"]) for row in rows})
        names = list(dict.fromkeys(row["implementation"] for row in rows))
        cells = {(row["implementation"], int(row["num_envs"])): row for row in rows}
        table = []
        for name in names:
            table.append([name] + [
                f"{_mega(cells[name, n]['steps_per_s'])} (x{float(cells[name, n]['speed_vs_gymnax']):.2f})"
                if (name, n) in cells else "–" for n in counts
            ])
        lines += ["Env steps per second (minimum over interleaved repeats) and, in brackets, speed relative to "
                  "gymnax in the same run:", ""]
        lines += _table(["implementation"] + [f"N={n}" for n in counts], table)
        if all(("lerax_like Euler", n) in cells for n in counts):
            table = [
                [name] + [f"{float(cells['lerax_like Euler', n]['steps_per_s']) / float(cells[name, n]['steps_per_s']):.2f}"
                          for n in counts]
                for name in ("lerax_like RK4", "lerax_like Tsit5") if all((name, n) in cells for n in counts)
            ]
            if table:
                lines += ["Cost relative to lerax_like Euler:", ""]
                lines += _table(["solver"] + [f"N={n}" for n in counts], table)
        if (folder / f"{stem}.png").exists():
            lines += [f"![throughput]({link}/{stem}.png)", ""]
    return lines


def profile_step(folder, link):
    if (rows := _read_csv(folder, "profile_step.csv")) is None:
        return []
    return ["Each row adds one part of `env.step` to the previous workload; time relative to gymnax's step "
            "(minimum of interleaved repeats):", ""] + _table(
        ["variant", "time vs gymnax", "M steps/s"],
        [[row["variant"], f"{float(row['time_vs_gymnax']):.2f}", _g(float(row["steps_per_s"]) / 1e6)] for row in rows],
    )


def compile_time(folder, link):
    rows = _read_csv(folder, "compile_time.csv")
    if rows is None:
        return []
    implementations = list(dict.fromkeys(row["implementation"] for row in rows))
    programs = list(dict.fromkeys(row["program"] for row in rows))
    cells = {(row["implementation"], row["program"]): row for row in rows}
    table = [[program] + [f"{float(cells[i, program]['total_wall_s']):.2f} s" if (i, program) in cells else "–"
                          for i in implementations] for program in programs]
    return ["Trace, lowering and XLA compilation of a fresh `jax.jit`, wall-clock, minimum of fresh compiles "
            "(`rollout`: `lerax_like.rollout` of one env; `step`: `env.step` with autoreset and random actions, "
            "vmapped):", ""] + _table(["program", *implementations], table)


def contact_compile(folder, link):
    rows = _read_csv(folder, "contact_compile.csv")
    if rows is None:
        return []
    return ["Trace, lowering and XLA compilation of a fresh `jax.jit` of a loss over `CartPoleContinuous` "
            "(4 envs x 12 steps), wall-clock, minimum of fresh compiles, and against the same program "
            "without events (`smooth`):", ""] + _table(
        ["solver", "program", "scene", "trace + lowering", "compile", "total", "vs smooth"],
        [[row["solver"], row["program"], row["scene"], f"{float(row['trace_lower_s']):.2f} s",
          f"{float(row['compile_s']):.2f} s", f"{float(row['total_s']):.2f} s", f"{float(row['vs_smooth']):.1f}x"]
         for row in rows],
    )


def adaptive_vmap(folder, link):
    lines = []
    for header, rows, _ in _runs(folder, "adaptive_vmap"):
        lines += header
        lines += _table(
            ["batch", "time vs all easy", "solver steps per env step (mean)", "loop iterations (max over batch)"],
            [[row["batch"], f"{float(row['time_vs_all_easy']):.2f}", _g(row["mean_solver_steps"]),
              _g(row["max_over_batch_solver_steps"])] for row in rows],
        )
    return lines


def latency(folder, link):
    rows = _read_csv(folder, "latency.csv")
    if rows is None:
        return []
    single = [row for row in rows if row["vs_jax_floor"] not in ("", "nan")]
    vector = [row for row in rows if row["vs_jax_floor"] in ("", "nan")]
    lines = ["Single env, median call per block, minimum over interleaved blocks:", ""]
    lines += _table(
        ["measurement", "µs per step", "vs JAX floor", "vs Gymnasium's `make` step"],
        [[row["measurement"], f"{float(row['seconds_per_step']) * 1e6:.3g}", f"{float(row['vs_jax_floor']):.2f}",
          f"{float(row['vs_gymnasium_make_step']):.2f}"] for row in single],
    )
    if vector:
        theirs = next((row for row in vector if row["measurement"].startswith("Gymnasium")), None)
        lines += ["Vector envs:", ""]
        lines += _table(
            ["measurement", "µs per vector step", "M steps/s", "vs Gymnasium vector"],
            [[row["measurement"], f"{float(row['seconds_per_step']) * 1e6:.3g}", _g(float(row["steps_per_s"]) / 1e6),
              f"{float(theirs['seconds_per_step']) / float(row['seconds_per_step']):.2f}x" if theirs else ""]
             for row in vector],
        )
    return lines


def gym_vector(folder, link):
    rows = _read_csv(folder, "gym_vector.csv")
    if rows is None:
        return []
    if "ours_steps_per_s" in rows[0]:
        return ["Steps per second of the vector env (fastest interleaved block), against a hand-written JAX step "
                "of the same physics (the XLA floor) and against Gymnasium's own vector env in the same run; "
                "`dispatch` is JAX's CPU dispatch in that run (`async`, the default, or `inline`: "
                "`jax_cpu_enable_async_dispatch` off):", ""] + _table(
            ["id", "N", "dtype", "dispatch", "ours", "floor", "ours / floor", "Gymnasium's", "ours / Gymnasium's", "load"],
            [[row["id"], row["num_envs"], row["dtype"], row.get("dispatch", "async"), _mega(row["ours_steps_per_s"]),
              _mega(row["floor_steps_per_s"]), f"{float(row['ours_vs_floor']):.2f}",
              f"{_mega(row['peer_steps_per_s'])} ({row['peer']})" if row["peer_steps_per_s"] else "",
              f"{float(row['ours_vs_peer']):.2f}" if row["ours_vs_peer"] else "", row["load_average_1min"]]
             for row in rows],
        )
    return _table(
        ["N", "lerax_like steps/s (median)", "Gymnasium steps/s (median)", "ratio (median)", "ratio (best)", "load"],
        [[row["num_envs"], _mega(row["lerax_like_steps_per_s_median"]), _mega(row["gymnasium_steps_per_s_median"]),
          f"{float(row['ratio_median']):.2f}", f"{float(row['ratio_best']):.2f}", row["load_average_1min"]]
         for row in rows],
    )


def stability(folder, link):
    rows = _read_csv(folder, "stability.csv")
    if rows is None:
        return []
    solvers = list(dict.fromkeys(row["solver"] for row in rows))
    table = []
    for case in dict.fromkeys(row["case"] for row in rows):
        cells = [case]
        for solver in solvers:
            row = next((r for r in rows if r["case"] == case and r["solver"] == solver), None)
            if row is None:
                cells.append("")
                continue
            cell = row["status"]
            if row["error"] and row["status"] != "ok":
                cell += f" ({row['error']})"
            elif row["failed_at"]:
                cell += f" (step {row['failed_at']})"
            cells.append(cell)
        table.append(cells)
    lines = ["Status per case and solver (ok: relative error at most 1e-3 against SciPy at 1e-12; in brackets the "
             "error, or the env step where the run failed); every number in "
             f"[`stability.md`]({link}/stability.md):", ""]
    lines += _table(["case", *solvers], table)
    markdown = folder / "stability.md"
    if markdown.exists():
        contact = [line for line in markdown.read_text().splitlines() if line.startswith("Contact reference:")]
        lines += contact + ([""] if contact else [])
    finders = _read_csv(folder, "root_finders.csv")
    if finders:
        lines += ["Kvaerno5's root finders on Van der Pol at mu = 1e3:", ""]
        lines += _table(list(finders[0]), [list(row.values()) for row in finders])
    return lines


def domain_randomisation(folder, link):
    data = _read_json(folder, "domain_randomisation.json")
    if data is None:
        return []
    masses = list(data["runs"][0]["balanced_fraction_by_pole_mass"])
    low, high = data["training_mass_range"]
    lines = [
        f"Fraction of {data['evaluation']}, per pole mass (kg); training range [{low:g}, {high:g}] kg in bold; "
        "where the seeds differ, the range over seeds.", "",
    ]
    table = []
    for policy in dict.fromkeys(run["policy"] for run in data["runs"]):
        runs = [run for run in data["runs"] if run["policy"] == policy]
        seeds = ", ".join(str(run["seed"]) for run in runs)
        cells = []
        for mass in masses:
            values = [run["balanced_fraction_by_pole_mass"][mass] for run in runs]
            cells.append(f"{min(values):.2f}" if min(values) == max(values) else f"{min(values):.2f}–{max(values):.2f}")
        label = f"nominal {data['nominal_mass']:g} kg" if policy == "nominal" else f"{policy} [{low:g}, {high:g}] kg"
        table.append([f"{label}, seeds {seeds}", *cells])
    lqr = data.get("lqr_per_mass")
    if lqr:
        table.append(["LQR designed at each mass", *(f"{lqr[mass]:.2f}" if mass in lqr else "" for mass in masses)])
    header = ["policy"] + [f"**{float(m):g}**" if low <= float(m) <= high else f"{float(m):g}" for m in masses]
    lines += _table(header, table)
    seconds = [run["train_seconds"] for run in data["runs"]]
    lines += [f"Training time per policy (compilation included): {min(seconds):g} to {max(seconds):g} s.", ""]
    return lines


def ppo_baseline(folder, link):
    data = _read_json(folder, "ppo_baseline.json")
    if data is None:
        return []
    starts = data.get("evaluation_starts", 100)
    balanced = data.get("balanced_500", data.get("balanced_500_of_100"))
    return [
        f"{data['algorithm']}: {data['env_steps']} env steps, {data['train_seconds']:.0f} s of training; its "
        f"deterministic policy balanced {balanced} of {starts} random starts for 500 steps (mean episode length "
        f"{data['mean_episode_length']:g}).", "",
    ]


def _load(data: dict) -> str:
    return f"load average {data['load_average_before'][0]} before, {data['load_average_after'][0]} after"


def sb3_vector(folder, link):
    data = _read_json(folder, "sb3_vector.json")
    if data is None:
        return []
    recipe, seconds, returns = data["recipe"], data["fastest_seconds"], data["mean_return"]
    speed = data["env_steps_per_s"]
    lines = [
        f"PPO ({recipe['policy']}, seed {recipe['seed']}, n_steps={recipe['n_steps']}, {recipe['n_envs']} envs, "
        f"{recipe['total_timesteps']} steps; {recipe['evaluation']}), runs in the order {', '.join(data['order'])}; "
        f"{_load(data)}:", "",
    ]
    lines += _table(
        ["VecEnv", "mean return", "fastest training (s)"],
        [["`lerax_like.sb3.make_vec_env`", f"{returns['lerax_like']:g}", f"{seconds['lerax_like']:.1f}"],
         ["SB3's `make_vec_env` (DummyVecEnv)", f"{returns['gymnasium']:g}", f"{seconds['gymnasium']:.1f}"]],
    )
    median = data.get("median_wall_time_ratio_lerax_like_vs_sb3")
    opted_out = data.get("async_wall_time_ratio_lerax_like_vs_sb3")
    lines += [
        f"Return ratio {data['return_ratio_lerax_like_vs_sb3']:.2f}, wall-time ratio "
        f"{data['wall_time_ratio_lerax_like_vs_sb3']:.2f} (lerax_like / SB3, fastest runs"
        + (f"; {median:.2f} by the median runs" if median is not None else "")
        + (f"; {opted_out:.2f} with `inline_dispatch=False`, JAX's asynchronous dispatch" if opted_out is not None else "")
        + ")."
        + (f" The VecEnv's step as PPO calls it: {data['median_step_us_in_ppo']['lerax_like']:g} us against "
           f"{data['median_step_us_in_ppo']['gymnasium']:g} us (median runs)."
           if "median_step_us_in_ppo" in data else "")
        + " The VecEnvs alone, random actions: "
        f"{speed['lerax_like_n8']:,} against {speed['gymnasium_n8']:,} steps/s at 8 envs, "
        f"{speed['lerax_like_n256']:,} against {speed['gymnasium_n256']:,} at 256.", "",
    ]
    if "env_speedup" in data:
        lines += _table(
            ["JAX's CPU dispatch", "n_envs", "lerax_like / SB3 env steps per s (fastest round)", "(median round)"],
            [[dispatch, n_envs, f"{ratios['fastest']:.2f}", f"{ratios['median']:.2f}"]
             for key, ratios in data["env_speedup"].items() for dispatch, n_envs in [key.split("_n")]],
        )
    return lines


def cleanrl_loop(folder, link):
    rows, data = _read_csv(folder, "cleanrl_loop.csv"), _read_json(folder, "cleanrl_loop.json")
    if rows is None or data is None:
        return []
    recipe = data["recipe"]
    return [
        f"Gymnasium's `SyncVectorEnv` of {recipe['num_envs']} envs from `gymnasium.make`, {recipe['env_steps']} env "
        f"steps of {recipe['actions']} actions, each run a fresh process, {recipe['rounds']} interleaved rounds "
        f"(medians); {_load(data)}:", "",
    ] + _table(
        ["env", "persistent compilation cache", "import (s)", "setup: make, reset, first step (s)",
         "of which backend compile (s)", "vector step (us)", "step / Gymnasium's", "process (s)",
         "process / Gymnasium's"],
        [[f"`{row['env_id']}`", row["persistent_cache"], _g(row["import_s"]), _g(row["setup_s"]),
          _g(row["backend_compile_s"]) or "-", _g(row["step_us"]), _g(row["step_ratio"]), _g(row["process_s"]),
          _g(row["process_ratio"])]
         for row in rows],
    )


def jax_rl(folder, link):
    rows, data = _read_csv(folder, "jax_rl.csv"), _read_json(folder, "jax_rl.json")
    if rows is None or data is None:
        return []
    recipe = data["recipe"]
    lines = [
        f"rejax's PPO, its CartPole config ({recipe['total_timesteps']} steps, {recipe['num_envs']} envs, evaluation "
        f"every {recipe['eval_freq']} steps), {recipe['seeds']} seeds vmapped, {recipe['precision']}, "
        f"{recipe['rounds']} interleaved rounds; load average {data['load_average_before'][0]} before, "
        f"{data['load_average_after'][0]} after:", "",
    ]
    return lines + _table(
        ["env", "training time / gymnax's (fastest)", "(median)", "fastest (s)", "compile (s)", "final return"],
        [[row["env"], row["time_ratio_fastest"], row["time_ratio_median"], row["fastest_s"], row["compile_s"],
          f"{row['final_return_mean']} +- {row['final_return_std']}"] for row in rows],
    )


def render(folder, link):
    rows = _read_csv(folder, "render.csv")
    if rows is None:
        return []
    first = rows[0]
    lines = [
        f"Milliseconds per frame, median call of {first['frames']}-frame blocks, fastest of "
        f"{first['repeats']} interleaved blocks; load average {first['load_average_before']} before, "
        f"{first['load_average_after']} after:", "",
    ]
    lines += _table(
        ["scene", "renderer", "ms per frame", "vs Gymnasium's CartPole (pygame)"],
        [[row["scene"], row["renderer"], _g(row["ms_per_frame"]), _g(row["vs_gymnasium_cartpole"])] for row in rows],
    )
    return lines


def sharded_rollout(folder, link):
    data = _read_json(folder, "sharded_rollout.json")
    if data is None:
        return []
    return [
        f"{data['num_envs']} envs on {data['devices']} devices in {data['processes']} process(es), {data['steps']} "
        f"steps: largest difference from the unsharded run {data['largest_difference_from_unsharded']:g}.", "",
    ]


def gym_before_after(folder, link):
    rows = _read_csv(folder, "gym_before_after.csv")
    if rows is None:
        return []
    first = rows[0]
    lines = [
        f"Commit {first['new_commit']} against {first['old_commit']}, {first['rounds']} interleaved rounds, fastest of "
        f"{first['blocks']} blocks; load average {first['load_average_before']} before, "
        f"{first['load_average_after']} after:", "",
    ]
    lines += _table(
        ["front end", "id", "envs", "old steps/s", "new steps/s", "new / old (wall)", "new / old (CPU time)"],
        [[row["front_end"], row["id"], row["num_envs"], f"{int(row['old_steps_per_s']):,}",
          f"{int(row['new_steps_per_s']):,}", row["new_vs_old"], row["new_vs_old_cpu_time"]] for row in rows],
    )
    return lines


def contact_study(folder, link):
    data = _read_json(folder, "contact_study.json")
    if data is None:
        return []
    rows = []
    for name, entry in data.items():
        for order in entry["orders"]:
            rows.append([name, ", ".join(f"{k}={v:g}" for k, v in entry["scene_kwargs"].items()), order["solver"],
                         order["method_order"], _g(order["order"]), order["points"]])
    lines = ["Fitted orders of the final-time error (fixed steps) on CartPoleContinuous through contact:", ""]
    lines += _table(["contact", "keywords", "solver", "method order", "fitted order", "points"], rows)
    for name in data:
        if (folder / f"contact_study_{name}.png").exists():
            lines += [f"![{name}]({link}/contact_study_{name}.png)", ""]
    return lines


def rimless_wheel(folder, link):
    data = _read_json(folder, "rimless_wheel.json")
    if data is None:
        return []
    parameters = ", ".join(f"{name} {value:.6g}" for name, value in data["parameters"].items())
    rows = [
        ["closed form", f"{data['closed_form_post_impact_speed']:.12f}", ""],
        [f"env, {len(data['starts'])} starts ({data['solver']})", f"{data['env_post_impact_speed']:.12f}",
         f"{data['env_max_abs_error']:.2e}"],
        ["SciPy solve_ivp with events (DOP853, 1e-13)", f"{data['scipy_post_impact_speed']:.12f}", f"{data['scipy_abs_error']:.2e}"],
    ]
    lines = [f"Passive rimless wheel ({parameters}), post-impact theta_dot of the limit cycle after "
             f"{data['env_steps']} env steps:", ""]
    lines += _table(["source", "theta_dot+ (rad/s)", "max abs error against the closed form"], rows)
    if (folder / "rimless_wheel.png").exists():
        lines += [f"![phase portrait]({link}/rimless_wheel.png)", ""]
    return lines


def walkers(folder, link):
    data = _read_json(folder, "walkers.json")
    if data is None:
        return []
    simplest, compass = data["simplest_walker"], data["compass_gait"]
    rows = []
    for name in ("long_period", "short_period"):
        point = min(simplest[name], key=lambda point: abs(point["slope"] - 0.009))
        rows.append([f"simplest walker, {name.replace('_', '-')}", f"{point['slope']:.6g}",
                     ", ".join(f"{value:.10f}" for value in point["fixed_point"]), f"{point['period']:.8f}",
                     f"{point['spectral_radius']:.6f}"])
    nominal = compass["nominal"]
    rows.append(["compass gait, nominal", f"{nominal['slope']:.6g}", ", ".join(f"{value:.10f}" for value in nominal["fixed_point"]),
                 f"{nominal['period']:.8f}", f"{nominal['spectral_radius']:.6f}"])
    lines = _table(["gait", "slope (rad)", "fixed point", "step period", "largest |eigenvalue|"], rows)
    lines += [f"First period doubling: simplest walker at gamma = {simplest['period_doubling']['slope']:.8f} rad, "
              f"compass gait at {compass['period_doubling']['slope_degrees']:.6f} deg.", ""]
    if (folder / "walkers.png").exists():
        lines += [f"![gaits against slope; compass-gait limit cycle]({link}/walkers.png)", ""]
    return lines


def contact(folder, link):
    rows = _read_csv(folder, "contact.csv")
    if rows is None:
        return []
    table = [
        [row["model"], _mega(row["forward_steps_per_s"]), _mega(row["value_and_grad_steps_per_s"]),
         _g(row["max_error"]), _g(row["median_error"]), _g(row["max_penetration_m"]),
         _g(row["solver_ok_fraction"]), _g(row["mean_impacts"]) if row["model"] == "located" else "not counted"]
        for row in rows
    ]
    by_model = {row["model"]: row for row in rows}
    lines = [
        f"N = {rows[0]['envs']} vmapped envs ({rows[0].get('gradient_envs', rows[0]['envs'])} for the value and "
        f"gradient), {rows[0]['steps']} steps; throughput in env steps per second; "
        "errors are the largest state error over the rollout against the SciPy reference (first 16 envs).", "",
    ]
    lines += _table(["model", "forward", "value and gradient", "max error", "median error", "max penetration (m)",
                     "solver_ok", "impacts per env"], table)
    if {"located", "penalty"} <= set(by_model):
        located, penalty = by_model["located"], by_model["penalty"]
        ratio = float(located["forward_steps_per_s"]) / float(penalty["forward_steps_per_s"])
        gradient_ratio = float(located["value_and_grad_steps_per_s"]) / float(penalty["value_and_grad_steps_per_s"])
        lines += [f"Located over penalty: {ratio:.3g}x forward, {gradient_ratio:.3g}x value and gradient.", ""]
    sweep = _read_csv(folder, "contact_sweep.csv")
    if sweep:
        worst = max(float(row["relative_error"]) for row in sweep)
        lines += [f"AD against central FD across the restitution sweep: largest relative error {worst:.2g}.", ""]
    for figure in ("contact_trajectory.png", "contact_gradients.png"):
        if (folder / figure).exists():
            lines += [f"![{figure}]({link}/{figure})", ""]
    return lines


def friction(folder, link):
    rows = _read_csv(folder, "friction.csv")
    if rows is None:
        return []
    table = [
        [row["model"], _g(row["epsilon"]) if row["model"] == "tanh" else "located", _mega(row["forward_steps_per_s"]),
         _mega(row["value_and_grad_steps_per_s"]), _g(row["distance_relative_error"]),
         _g(row["derivative_relative_error"]), _g(row["solver_ok_fraction"])]
        for row in rows
    ]
    lines = [
        f"N = {rows[0]['envs']} vmapped SlidingBlocks launched at 0.5 to 2 m/s, {rows[0]['steps']} steps of 0.05 s; "
        "throughput in env steps per second; errors relative to the closed forms of the stop distance and its "
        "derivative in mu_k.", "",
    ]
    lines += _table(["model", "epsilon", "forward", "value and gradient", "distance error", "d/dmu_k error",
                     "solver_ok"], table)
    by_model = {row["model"]: row for row in rows}
    if {"located", "tanh"} <= set(by_model):
        located, smooth = by_model["located"], by_model["tanh"]
        ratio = float(located["forward_steps_per_s"]) / float(smooth["forward_steps_per_s"])
        gradient_ratio = float(located["value_and_grad_steps_per_s"]) / float(smooth["value_and_grad_steps_per_s"])
        lines += [f"Located over tanh: {ratio:.3g}x forward, {gradient_ratio:.3g}x value and gradient.", ""]
    return lines


def frictional_contact(folder, link):
    rows = _read_csv(folder, "frictional_contact.csv")
    if rows is None:
        return []
    table = [
        [row["model"], _g(row["position_error"]),
         _g(row["derivative_error"]) if float(row["derivative_finite_fraction"]) == 1 else
         f"not finite ({_g(row['derivative_finite_fraction'])} finite)", _g(row["solver_steps_per_env"]),
         _duration(row["forward_s"]), _duration(row["value_and_grad_s"]), _g(row["gradient_over_forward"]),
         _g(row["gradient_compile_s"]), _g(float(row["gradient_temp_bytes"]) / 2**20), _g(row["solver_ok_fraction"])]
        for row in rows
    ]
    lines = [
        f"N = {rows[0]['envs']} vmapped disks launched sliding at 2 m/s, mu_k from 0.25 to 0.75, {rows[0]['steps']} "
        "steps of 0.05 s; errors are the largest absolute errors of x(T) (m) and dx(T)/dmu (m) against the closed "
        "forms; steps per disk over the rollout; times the median of the interleaved repeats (one call where a "
        "call takes over 30 s); compile in s; memory XLA's temporaries of the compiled value and gradient (MiB).", "",
    ]
    lines += _table(["model", "x(T) error", "dx/dmu error", "steps", "forward", "value and gradient",
                     "gradient / forward", "gradient compile", "gradient MiB", "solver_ok"], table)
    located = rows[0]
    ratios = [f"{row['model']} {float(row['forward_s']) / float(located['forward_s']):.3g}x forward, "
              f"{float(row['value_and_grad_s']) / float(located['value_and_grad_s']):.3g}x value and gradient"
              for row in rows[1:]]
    lines += ["Each model's time over the located model's (reverse mode): " + "; ".join(ratios) + ".", ""]
    scale = _read_csv(folder, "frictional_contact_scale.csv")
    if scale:
        lines += _table(
            ["workload", "envs", "steps", "forward", "value and gradient", "gradient / forward", "gradient compile (s)",
             "gradient MiB", "solver_ok"],
            [[row["workload"], row["envs"], row["steps"], _duration(row["forward_s"]), _duration(row["value_and_grad_s"]),
              _g(row["gradient_over_forward"]), _g(row["gradient_compile_s"]),
              _g(float(row["gradient_temp_bytes"]) / 2**20), _g(row["solver_ok_fraction"])] for row in scale],
        )
    return lines


def friction_bias(folder, link):
    rows = _read_csv(folder, "friction_bias.csv")
    if rows is None:
        return []
    table = [
        [row["model"], _g(row["epsilon"]) if row["model"] == "tanh" else "located", _g(row["distance_relative_error"]),
         _g(row["reverse_bias"]), _g(row["forward_bias"]), _g(row["differences_bias"]),
         _g(row["ad_against_differences"]), row["solver_ok"]]
        for row in rows
    ]
    lines = [
        f"{rows[0]['blocks']} SlidingBlocks launched at 0.5 to 2 m/s, {rows[0]['steps']} steps of 0.05 s; largest "
        "relative errors against the closed forms of the stop distance and of its derivative in mu_k.", "",
    ]
    lines += _table(["model", "epsilon", "distance error", "reverse AD bias", "forward AD bias",
                     "differences bias", "AD against differences", "solver_ok"], table)
    if (folder / "friction_bias.png").exists():
        lines += [f"![friction_bias.png]({link}/friction_bias.png)", ""]
    return lines


SECTIONS = {
    "work_precision": work_precision,
    "gradient_error": gradient_error,
    "gradient_variance": gradient_variance,
    "contact_gradient_variance": contact_gradient_variance,
    "gradient_precision": gradient_precision,
    "gradient_memory": gradient_memory,
    "gradient_cost": gradient_cost,
    "throughput": throughput,
    "profile_step": profile_step,
    "compile_time": compile_time,
    "contact_compile": contact_compile,
    "adaptive_vmap": adaptive_vmap,
    "latency": latency,
    "gym_vector": gym_vector,
    "contact_study": contact_study,
    "rimless_wheel": rimless_wheel,
    "walkers": walkers,
    "stability": stability,
    "domain_randomisation": domain_randomisation,
    "ppo_baseline": ppo_baseline,
    "jax_rl": jax_rl,
    "sb3_vector": sb3_vector,
    "cleanrl_loop": cleanrl_loop,
    "gym_before_after": gym_before_after,
    "contact": contact,
    "render": render,
    "friction": friction,
    "frictional_contact": frictional_contact,
    "friction_bias": friction_bias,
    "sharded_rollout": sharded_rollout,
}
assert set(SECTIONS) == set(BENCHMARKS), "every benchmark needs a section"

# How to read each benchmark's tables: method and caveats, no numbers (those come from the files).
NOTES_FILE = HERE / "NOTES.md"


def _notes() -> dict[str, str]:
    """`## name` sections of benchmarks/NOTES.md, by benchmark name."""
    notes, name = {}, None
    if NOTES_FILE.exists():
        for line in NOTES_FILE.read_text().splitlines():
            if line.startswith("## "):
                name = line[3:].strip()
                notes[name] = []
            elif name is not None:
                notes[name].append(line)
    return {name: "\n".join(lines).strip() for name, lines in notes.items()}


def render(folder: pathlib.Path, link: str, quick: bool) -> str:
    notes = _notes()
    lines = [
        "# Benchmark results" + (" (quick run)" if quick else ""),
        "",
        "<!-- Generated by `python -m benchmarks report` from the files in "
        f"{'benchmarks/results/quick' if quick else 'benchmarks/results'}/; do not edit by hand. -->",
        "",
        "Written by `python -m benchmarks NAME|all" + (" --quick" if quick else "") + "` (or `python -m benchmarks "
        "report`) from the result files alone: every number below is read from a file under "
        f"[`{link}/`]({link}/), and each section names the command that wrote its files. Timings come from a "
        "shared 2-core CPU machine unless a section says otherwise: compare the ratios between peers measured in "
        "the same run, not absolute times across sections. The paragraphs after the tables (how to read them, "
        "what was learnt) come from `benchmarks/NOTES.md` and carry no measured numbers.",
        "",
    ]
    for name, section in SECTIONS.items():
        lines += [f"## {name}", "", summary_line(name).rstrip(".") + ".", ""]
        body = section(folder, link)
        if not body:
            lines += [f"*No results recorded yet: `python -m benchmarks {name}`.*", ""]
            continue
        lines += provenance(folder, name) + body
        if notes.get(name):
            lines += [notes[name], ""]
    return "\n".join(lines).rstrip() + "\n"


# Docs pages that show a benchmark's table between `<!-- NAME table: ... -->` and
# `<!-- end of the NAME table -->`: rewritten with RESULTS.md, so that the page and the record agree.
DOCS_TABLES = {
    "gradient_cost": HERE.parent / "docs" / "gradients.md",
    "frictional_contact": HERE.parent / "docs" / "friction.md",
}


def _write_docs_tables(folder) -> None:
    for name, page in DOCS_TABLES.items():
        text = page.read_text()
        start = text.index(f"<!-- {name} table:")
        start = text.index("\n", start) + 1
        end = text.index(f"<!-- end of the {name} table -->")
        link = os.path.relpath(folder, page.parent)
        body = provenance(folder, name) + SECTIONS[name](folder, link)
        page.write_text(text[:start] + "\n".join(body).strip() + "\n" + text[end:])


def write_results(quick: bool = False) -> pathlib.Path:
    folder = results_dir(quick)
    path = folder / "RESULTS.md" if quick else HERE / "RESULTS.md"
    link = os.path.relpath(folder, path.parent)
    folder.mkdir(parents=True, exist_ok=True)
    path.write_text(render(folder, link, quick))
    if not quick:
        _write_docs_tables(folder)
    return path
