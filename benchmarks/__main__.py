"""`python -m benchmarks NAME|all|list|report [--quick] [-- OPTIONS]`: see `benchmarks/__init__.py`."""

import argparse
import datetime
import hashlib
import importlib.util
import json
import os
import platform
import shlex
import subprocess
import sys
import time

from benchmarks import BENCHMARKS, HERE, results_dir
from benchmarks._report import write_results


REPOSITORY = HERE.parent


def missing_peers(name: str) -> list[str]:
    return [
        f"{module} ({hint})" for module, hint in BENCHMARKS[name].needs if importlib.util.find_spec(module) is None
    ]


def _versions() -> dict[str, str]:
    from importlib import metadata

    versions = {}
    for package in ("jax", "jaxlib", "diffrax", "equinox", "gymnasium", "gymnax", "numpy", "scipy",
                    "stable_baselines3", "torch"):
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            pass
    return versions


def _sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def run_one(name: str, quick: bool, options: list[str]) -> tuple[str, float]:
    """Runs `benchmarks.NAME` in its own process (JAX settings such as float64 stay in it);
    writes its console output to `NAME.txt` and the record `NAME.run.json`."""
    missing = missing_peers(name)
    if missing:
        print(f"== {name}: skipped, needs " + ", ".join(missing), flush=True)
        return "skipped: needs " + ", ".join(missing), 0.0
    out = results_dir(quick)
    out.mkdir(parents=True, exist_ok=True)
    command = ["python", "-m", "benchmarks", name] + (["--quick"] if quick else []) + (["--", *options] if options else [])
    print(f"== {name}: {shlex.join(command)}", flush=True)
    arguments = [sys.executable, "-m", f"benchmarks.{name}", "--out", str(out)] + (["--quick"] if quick else []) + options
    environment = {**os.environ, **dict(BENCHMARKS[name].environment)}
    load = os.getloadavg()
    started = time.time()
    process = subprocess.Popen(arguments, cwd=REPOSITORY, env=environment, stdout=subprocess.PIPE, text=True)
    lines = []
    for line in process.stdout:
        sys.stdout.write(line)
        sys.stdout.flush()
        lines.append(line)
    code = process.wait()
    seconds = time.time() - started
    log = out / f"{name}.txt"
    log.write_text("".join(lines))
    if code != 0:
        print(f"== {name}: FAILED (exit {code}) after {seconds:.0f} s", flush=True)
        return f"failed (exit {code})", seconds
    written = sorted(
        path for path in out.iterdir()
        if path.is_file() and path.stat().st_mtime >= started - 1 and not path.name.endswith(".run.json")
        and path.name != "RESULTS.md"
    )
    record = {
        "benchmark": name,
        "command": shlex.join(command),
        "date_utc": datetime.datetime.fromtimestamp(started, datetime.timezone.utc).strftime("%Y-%m-%d %H:%M"),
        "seconds": round(seconds, 1),
        "load_average_at_start": [round(value, 2) for value in load],
        "load_average_at_end": [round(value, 2) for value in os.getloadavg()],
        "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} CPUs",
        "python": platform.python_version(),
        "versions": _versions(),
        "files": {path.name: _sha256(path) for path in written},
    }
    (out / f"{name}.run.json").write_text(json.dumps(record, indent=1) + "\n")
    print(f"== {name}: done in {seconds:.0f} s", flush=True)
    return "ok", seconds


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    options = []
    if "--" in argv:
        split = argv.index("--")
        argv, options = argv[:split], argv[split + 1:]
    parser = argparse.ArgumentParser(
        prog="python -m benchmarks", description=__doc__.splitlines()[0],
        epilog="benchmarks: " + ", ".join(BENCHMARKS),
    )
    parser.add_argument("name", help="a benchmark, 'all', 'list' or 'report'")
    parser.add_argument("--quick", action="store_true", help="small sizes, into results/quick/ (git-ignored)")
    arguments = parser.parse_args(argv)

    if arguments.name == "list":
        for name, benchmark in BENCHMARKS.items():
            missing = missing_peers(name)
            state = "ready" if not missing else "needs " + ", ".join(missing)
            print(f"{name:22s} {benchmark.summary} [{state}]")
        return 0
    if arguments.name == "report":
        print(f"wrote {write_results(quick=arguments.quick)}")
        return 0
    if arguments.name == "all":
        if options:
            parser.error("options after -- go to one benchmark, not to 'all'")
        names = list(BENCHMARKS)
    elif arguments.name in BENCHMARKS:
        names = [arguments.name]
    else:
        parser.error(f"unknown benchmark {arguments.name!r}; choose from: all, list, report, " + ", ".join(BENCHMARKS))

    started = time.time()
    outcomes = {name: run_one(name, arguments.quick, options) for name in names}
    print(f"wrote {write_results(quick=arguments.quick)}")
    print("== summary")
    for name, (outcome, seconds) in outcomes.items():
        print(f"{name:22s} {outcome:40s} {seconds:7.0f} s")
    print(f"total {time.time() - started:.0f} s")
    return 1 if any(outcome.startswith("failed") for outcome, _ in outcomes.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
