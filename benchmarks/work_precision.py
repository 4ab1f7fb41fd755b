"""Work-precision study of every solver on every scene present; results committed under results/.

    python benchmarks/work_precision.py [--scenes CartPole ...] [--out benchmarks/results]

For each scene in `lerax_like.analysis.SCENES`, runs the default (full) study of
`lerax-like study SCENE`, with the SciPy reference also checked against an independent
method (Radau against DOP853, or the other way round for stiff scenes), and writes
`work_precision_<scene>.csv`, `.png` and `.json` (the JSON holds the configuration,
library versions, the machine and the date). Timings are of this machine, in this run.
"""

import argparse
import datetime
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

from lerax_like.analysis import SCENES, StudyConfig, run_study  # noqa: E402
from lerax_like.analysis.report import (  # noqa: E402
    cheapest_at, format_orders, format_table, plot_work_precision, write_csv, write_json,
)
from lerax_like.analysis.study import environment_record  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    parser.add_argument("--repeats", type=int, default=15, help="timed runs per setting; the minimum is kept")
    parser.add_argument("--no-progress", action="store_true")
    arguments = parser.parse_args(argv)
    os.makedirs(arguments.out, exist_ok=True)
    for scene in arguments.scenes:
        date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        machine = environment_record()
        config = StudyConfig.default(
            scene, repeats=arguments.repeats, check_method="DOP853" if SCENES[scene].stiff else "Radau"
        )
        started = datetime.datetime.now()
        result = run_study(config, progress=not arguments.no_progress)
        seconds = (datetime.datetime.now() - started).total_seconds()
        stem = os.path.join(arguments.out, f"work_precision_{scene}")
        write_csv(result.rows, stem + ".csv")
        write_json(result, stem + ".json", date=date, study_seconds=seconds)
        title = (
            f"{scene}: work-precision, {config.schedules[0]} actions, {config.horizon} env steps "
            f"({date}; {machine['processor']}, {machine['cpu_count']} cores, jax {machine['versions']['jax']})"
        )
        plot_work_precision(result.rows, stem + ".png", title=title)
        print(f"== {scene} ({seconds:.0f} s) ==")
        print(format_table(result.rows))
        print(format_orders(result.convergence_orders()))
        for target in (1e-3, 1e-6, 1e-9):
            print(f"cheapest at error <= {target:g}:", cheapest_at(result.rows, target))
    return 0


if __name__ == "__main__":
    sys.exit(main())
