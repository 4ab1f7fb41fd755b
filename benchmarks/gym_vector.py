"""Steps per second of the vector env against the XLA floor and against Gymnasium, in one run.

    python -m benchmarks gym_vector                 # all five ids, N = 1024 and 16384, float64 and float32
    python -m benchmarks gym_vector --quick         # fewer steps and repeats, N = 1024
    python -m benchmarks.gym_vector --ids CartPole-v1 --num-envs 1024 [--out DIR]   # async and inline, each in a process

For each registered id, number of envs N and dtype, three vector envs step the same
pre-drawn random actions (sampled from the action space, seed 0; episodes end and restart
as they would in training):
- ours: `gymnasium.make_vec("lerax_like/<id>", N, vectorization_mode="vector_entry_point",
  dtype=...)`, with its autoreset, info and checks;
- the XLA floor: a minimal hand-written JAX step of the same physics at the same dtype
  (`_floors.py`: Gymnasium's equations, no autoreset, no checks, results fetched to NumPy);
- Gymnasium's peer (float64 only, it has no other): its vector CartPole for CartPole-v1,
  `SyncVectorEnv` of `gymnasium.make(<id>)` for the four without a vector entry point.
Each is warmed up first; blocks of `--steps` steps are interleaved over `--repeats` rounds,
so that load on the shared machine hits all alike, and the fastest block is kept, by wall
time and by process CPU time (the CPU time is the steadier on a loaded machine). The load
average is recorded. Writes benchmarks/results/gym_vector.csv (results/quick/ with --quick).

All of it twice, each in a process of its own (`--dispatch`): with JAX's default
asynchronous dispatch on the CPU, where each call hands its work to a thread of JAX's
and the caller waits for it, and with `jax_cpu_enable_async_dispatch` off ("inline"),
where a call runs in the calling thread. The setting is read once, when JAX starts its
CPU backend, hence the two processes.
"""

import argparse
import csv
import datetime
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium
import jax
import numpy as np


import lerax_like  # noqa: F401  (registers the lerax_like/ ids)
from benchmarks import results_dir
from benchmarks._floors import FloorVectorEnv
from lerax_like.gym import SPECS


# The ids that stand for Gymnasium's envs, which have a hand-written floor and a Gymnasium peer
# (the others, CartPoleContinuous-v0 and the like, have neither).
NAMES = tuple(spec.name for spec in SPECS.values() if spec.stands_for_gymnasium)
DISPATCH = ("async", "inline")


def peer(name: str, num_envs: int):
    """Gymnasium's fastest vector env of `name`: its own vector env if it has one, else `SyncVectorEnv`."""
    if gymnasium.spec(name).vector_entry_point is not None:
        return gymnasium.make_vec(name, num_envs=num_envs, vectorization_mode="vector_entry_point"), "vector_entry_point"
    return gymnasium.make_vec(name, num_envs=num_envs, vectorization_mode="sync"), "SyncVectorEnv"


def block(env, actions) -> tuple[float, float]:
    """Wall and CPU seconds of `len(actions)` steps."""
    wall, cpu = time.perf_counter(), time.process_time()
    for action in actions:
        env.step(action)
    return time.perf_counter() - wall, time.process_time() - cpu


def measure(name: str, num_envs: int, dtype: str, steps: int, repeats: int, with_peer: bool, dispatch: str) -> dict:
    ours = gymnasium.make_vec(f"lerax_like/{name}", num_envs=num_envs, vectorization_mode="vector_entry_point", dtype=dtype)
    ours.reset(seed=0)
    ours.action_space.seed(0)
    actions = [ours.action_space.sample() for _ in range(steps)]
    envs = {"ours": ours, "floor": FloorVectorEnv(name, ours.unwrapped.state.T, dtype)}
    peer_kind = ""
    if with_peer:
        envs["peer"], peer_kind = peer(name, num_envs)
        envs["peer"].reset(seed=0)
    for env in envs.values():
        block(env, actions[: min(10, steps)])  # warm-up
    walls = {key: [] for key in envs}
    cpus = {key: [] for key in envs}
    for _ in range(repeats):
        for key, env in envs.items():
            wall, cpu = block(env, actions)
            walls[key].append(wall)
            cpus[key].append(cpu)
    rate = {key: num_envs * steps / min(times) for key, times in walls.items()}
    cpu_rate = {key: num_envs * steps / min(times) for key, times in cpus.items()}
    for env in envs.values():
        env.close()
    row = {
        "id": f"lerax_like/{name}",
        "num_envs": num_envs,
        "dtype": dtype,
        "dispatch": dispatch,
        "ours_steps_per_s": round(rate["ours"]),
        "floor_steps_per_s": round(rate["floor"]),
        "ours_vs_floor": round(rate["ours"] / rate["floor"], 3),
        "ours_vs_floor_cpu_time": round(cpu_rate["ours"] / cpu_rate["floor"], 3),
        "peer": peer_kind,
        "peer_steps_per_s": round(rate["peer"]) if with_peer else "",
        "ours_vs_peer": round(rate["ours"] / rate["peer"], 3) if with_peer else "",
        "floor_vs_peer": round(rate["floor"] / rate["peer"], 3) if with_peer else "",
        "steps_per_block": steps,
        "repeats": repeats,
        "load_average_1min": round(os.getloadavg()[0], 1),
    }
    print(", ".join(f"{key}={value}" for key, value in row.items()), flush=True)
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ids", nargs="+", default=list(NAMES), choices=NAMES, help="Gymnasium names")
    parser.add_argument("--num-envs", type=int, nargs="+", default=None)
    parser.add_argument("--dtypes", nargs="+", default=["float64", "float32"], choices=["float64", "float32"])
    parser.add_argument("--steps", type=int, default=None, help="steps per timed block")
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--no-peer", action="store_true", help="skip Gymnasium's envs")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--dispatch", choices=DISPATCH, default=None, help="one setting (default: each in turn)")
    parser.add_argument("--out", type=Path, default=None, help="folder (default: benchmarks/results[/quick])")
    parser.add_argument("--output", type=Path, default=None, help="the CSV file (default: OUT/gym_vector.csv)")
    args = parser.parse_args(argv)
    num_envs = args.num_envs or ([1024] if args.quick else [1024, 16384])
    repeats = args.repeats or (3 if args.quick else 25)
    output = args.output or (args.out or results_dir(args.quick)) / "gym_vector.csv"
    if args.dispatch is None:
        write(each_dispatch(argv if argv is not None else sys.argv[1:]), output)
        return
    if jax.config.values["jax_cpu_enable_async_dispatch"] != (args.dispatch == "async"):
        # Set after `import lerax_like` started JAX's CPU client, the setting would do nothing.
        raise SystemExit(f"--dispatch {args.dispatch}: run through each_dispatch (no --dispatch), which sets it first")

    header = {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores",
        "jax": jax.__version__,
        "jax_backend": jax.default_backend(),
        "gymnasium": gymnasium.__version__,
    }
    print(header, flush=True)
    rows = []
    for n in num_envs:
        # Short blocks, many of them: on a loaded machine the fastest of many short blocks
        # is the one least disturbed. Fewer steps for the large batches (a SyncVectorEnv
        # step of 16384 envs takes a tenth of a second).
        steps = args.steps or (10 if n <= 4096 else 3)
        for name in args.ids:
            for dtype in args.dtypes:
                with_peer = not args.no_peer and dtype == "float64"
                rows.append({**header, **measure(name, n, dtype, steps, repeats, with_peer, args.dispatch)})
    write(rows, output)


def each_dispatch(argv: list[str]) -> list[dict]:
    """The rows of this benchmark run with each `DISPATCH` setting, each in a process of its own."""
    rows = []
    for dispatch in DISPATCH:
        with tempfile.TemporaryDirectory() as folder:
            output = Path(folder) / "gym_vector.csv"
            # JAX reads the setting once, when it starts its CPU client (JAX 0.10 does not
            # read it from the environment): the child sets it before this module does any
            # JAX work.
            setting = f"import jax; jax.config.update('jax_cpu_enable_async_dispatch', {dispatch == 'async'}); "
            runner = setting + "import runpy; runpy.run_module('benchmarks.gym_vector', run_name='__main__')"
            command = [sys.executable, "-c", runner, *argv, "--dispatch", dispatch, "--output", str(output)]
            subprocess.run(command, check=True)
            with output.open() as file:
                rows += list(csv.DictReader(file))
    return rows


def write(rows: list[dict], output: Path) -> None:
    output.parent.mkdir(parents=True, exist_ok=True)
    with output.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
