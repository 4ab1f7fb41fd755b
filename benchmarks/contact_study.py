"""Work-precision through contact: the walled cart-pole with located walls beside penalty end stops.

`lerax_like.analysis.run_study` on `CartPoleContinuous` with the rail's ends at
`track_limit = 0.1` m, once as walls located as events (`restitution = 0.8`, the env's
hybrid step) and once as penalty end stops (`end_stop_stiffness = 1e4` N/m), the same
random forces, starts and fixed-step sweeps of RK4 and Tsit5. The located walls' reference
is SciPy's `solve_ivp` (DOP853, 1e-13) with the same events, restarted at each impact
(`lerax_like.analysis.hybrid_reference`); the end stops' is the smooth penalty ODE at the
same tolerance. The fitted orders (log error on log step, between the reference floor and
1e-2) are the question: do located impacts keep a solver's order, does a penalty spring
lose it? Dense errors are left out (`dense_points = 1`): the solvers' own dense output
does not pass an impact.

    python -m benchmarks contact_study            # writes results/contact_study_*.csv/.json/.png
    python -m benchmarks contact_study --quick    # fewer settings, into results/quick/
"""

import argparse
import json
import pathlib
import time

import jax

jax.config.update("jax_enable_x64", True)

from benchmarks import results_dir  # noqa: E402
from lerax_like.analysis import SolverSweep, StudyConfig, run_study  # noqa: E402
from lerax_like.analysis.study import write_study  # noqa: E402

CONTACTS = {
    "walls": {"track_limit": 0.1, "restitution": 0.8},
    "end_stops": {"track_limit": 0.1, "end_stop_stiffness": 1e4},
}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    # Tsit5 from one step per env step: at two substeps and finer its error reaches the
    # reference floor within two halvings, too few points for a fit.
    sweeps = (SolverSweep("rk4", substeps=(2, 4, 8) if args.quick else (2, 4, 8, 16)),
              SolverSweep("tsit5", substeps=(1, 2, 4) if args.quick else (1, 2, 4, 8)))
    summary = {}
    for name, kwargs in CONTACTS.items():
        config = StudyConfig(
            scene="CartPoleContinuous", scene_kwargs=kwargs, sweeps=sweeps, schedules=("recorded",),
            # No dense grid through impacts (dense_points=1); the smooth penalty ODE keeps one
            # point inside, as SciPy's dense output needs a time to evaluate.
            horizon=25, batch=2, repeats=1, dense_points=1 if name == "walls" else 2,
        )
        started = time.perf_counter()
        result = run_study(config, progress=False)
        seconds = time.perf_counter() - started
        write_study(result, out, stem=f"contact_study_{name}", title=f"CartPoleContinuous, {name} at track_limit 0.1 m")
        orders = result.convergence_orders()
        # Each impact starts a new segment, which takes at least one extra solver step.
        extra = {f"{row['solver']} {row['substeps']}": row["steps"] - config.horizon * row["substeps"] for row in result.rows}
        summary[name] = {"scene_kwargs": kwargs, "orders": orders, "seconds": seconds, "extra_steps_per_trajectory": extra}
        for entry in orders:
            fitted = "none (fewer than two errors in range)" if entry["order"] is None else f"{entry['order']:.3f}"
            print(f"{name:<10} {entry['solver']:<6} fitted order {fitted} ({entry['points']} points; "
                  f"method order {entry['method_order']})")
        for row in result.rows:
            print(f"{name:<10} {row['solver']:<6} substeps {row['substeps']:>3}  error {row['error']:.3e}  "
                  f"steps {row['steps']:.0f}")
    (out / "contact_study.json").write_text(json.dumps(summary, indent=2, default=float) + "\n")


if __name__ == "__main__":
    main()
