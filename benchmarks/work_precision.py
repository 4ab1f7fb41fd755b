"""Work-precision studies of the solvers, committed under results/: CartPole and the stiff Van der Pol.

    python -m benchmarks work_precision             # CartPole and VanDerPol, the full studies
    python -m benchmarks work_precision --quick     # CartPole, `lerax-like study --quick` sizes
    python -m benchmarks.work_precision [--scenes CartPole VanDerPol ...] [--repeats 15] [--out DIR]

For each scene (default: CartPole, and Van der Pol at mu = 1e3 over [0, 3000], the
classic stiff test), runs the default (full) study of `lerax-like study SCENE`, with the
SciPy reference also checked against an independent method (Radau against DOP853; LSODA
against Radau for stiff scenes, where an explicit DOP853 at 1e-13 would take millions of
steps), and writes `work_precision_<scene>.csv`, `.png` and
`.json` (the JSON holds the configuration, library versions, the machine, the date and
the figure's legend). Timings are of this machine, in this run.
"""

import argparse
import datetime
import os

from benchmarks import results_dir
from lerax_like.analysis import SCENES, StudyConfig, run_study
from lerax_like.analysis.study import VERDICT_TARGETS, write_study
from lerax_like.analysis.tables import format_orders, format_table
from lerax_like.analysis.verdict import cheapest_at, verdict_line
from lerax_like.analysis.recording import environment_record


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="CartPole only, the quick study's sizes")
    parser.add_argument("--scenes", nargs="*", default=None, choices=sorted(SCENES),
                        help="default: CartPole and VanDerPol (CartPole only with --quick)")
    parser.add_argument("--out", default=None, help="default: benchmarks/results[/quick]")
    parser.add_argument("--repeats", type=int, default=None,
                        help="timed runs per setting, the minimum kept (default: 15; 3 for stiff scenes and --quick)")
    parser.add_argument("--no-progress", action="store_true")
    arguments = parser.parse_args(argv)
    scenes = arguments.scenes or (["CartPole"] if arguments.quick else ["CartPole", "VanDerPol"])
    out = arguments.out or results_dir(arguments.quick)
    os.makedirs(out, exist_ok=True)
    for scene in scenes:
        date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        machine = environment_record()
        stiff = SCENES[scene].stiff
        repeats = arguments.repeats or (3 if stiff or arguments.quick else 15)
        config = StudyConfig.default(
            scene, quick=arguments.quick, repeats=repeats, check_method="LSODA" if stiff else "Radau"
        )
        started = datetime.datetime.now()
        result = run_study(config, progress=not arguments.no_progress)
        seconds = (datetime.datetime.now() - started).total_seconds()
        span = config.horizon * result.record["dt"]
        title = (
            f"{scene}{' (mu = 1e3)' if stiff else ''}: {config.schedules[0]} actions, [0, {span:g}] s in "
            f"{config.horizon} env steps\n({date}; {machine['processor']}, {machine['cpu_count']} cores, "
            f"jax {machine['versions']['jax']})"
        )
        write_study(result, out, stem=f"work_precision_{scene}", title=title, date=date, study_seconds=seconds)
        print(f"== {scene} ({seconds:.0f} s) ==")
        print(format_table(result.rows))
        print(format_orders(result.convergence_orders()))
        for target in VERDICT_TARGETS:
            print(f"cheapest at error <= {target:g}: {verdict_line(cheapest_at(result.rows, target))}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
