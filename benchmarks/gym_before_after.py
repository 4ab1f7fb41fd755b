"""Throughput of the vector env and the SB3 VecEnv, two versions of the package interleaved in one run.

    python -m benchmarks gym_before_after [--quick] [-- --old-commit c47eebd --rounds 4]
    python -m benchmarks.gym_before_after [--old DIR | --old-commit REV] [--new DIR] [--rounds 4] [--out DIR]

`--old` and `--new` are checkouts (`--new` defaults to this one; without `--old`, a
temporary `git worktree` of `--old-commit`, c47eebd by default: the commit before the one
batched stepper, removed afterwards). Each round
starts one process per checkout, in ABBA order over the rounds, so that a drift of the
shared machine's load hits both alike; a process imports its checkout's `lerax_like`
(through the public API only: `gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")` and `lerax_like.sb3.make_vec_env`, which both versions have) and
times, for each configuration, blocks of steps with pre-drawn random actions (episodes
end and restart as in training), after a warm-up. A configuration's rate is its fastest
block over all rounds, by wall time and by process CPU time (the steadier on a loaded
machine); the ratio is new over old. Writes gym_before_after.csv under `--out`
(default benchmarks/results).
"""

import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks import benchmark_parser, output_folder
from benchmarks.gym_vector import write


# (kind, id, number of envs, steps per block)
CONFIGS = (
    ("vector", "lerax_like/CartPole-v1", 1024, 20),
    ("vector", "lerax_like/Pendulum-v1", 1024, 20),
    ("vector", "lerax_like/CartPole-v1", 16384, 5),
    ("vector", "lerax_like/Pendulum-v1", 16384, 5),
    ("sb3", "lerax_like/CartPole-v1", 8, 200),
    ("sb3", "lerax_like/CartPole-v1", 256, 40),
)

WORKER = r"""
import json, sys, time
import gymnasium, numpy as np
import lerax_like, lerax_like.sb3
configs, blocks = json.loads(sys.argv[1]), int(sys.argv[2])
results = []
for kind, env_id, num_envs, steps in configs:
    if kind == "vector":
        env = gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
        env.reset(seed=0)
        env.action_space.seed(0)
        actions = [env.action_space.sample() for _ in range(steps)]
    else:
        env = lerax_like.sb3.make_vec_env(env_id, n_envs=num_envs, seed=0)
        env.reset()
        actions = list(np.random.default_rng(0).integers(0, 2, size=(steps, num_envs)))
    for action in actions[:10]:
        env.step(action)
    walls, cpus = [], []
    for _ in range(blocks):
        wall, cpu = time.perf_counter(), time.process_time()
        for action in actions:
            env.step(action)
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    env.close()
    results.append({"wall": walls, "cpu": cpus})
print(json.dumps({"module": lerax_like.__file__, "results": results}))
"""


def run_worker(checkout: Path, blocks: int) -> dict:
    environment = {**os.environ, "PYTHONPATH": str(checkout)}
    output = subprocess.run(
        [sys.executable, "-c", WORKER, json.dumps(CONFIGS), str(blocks)], cwd=checkout, env=environment,
        capture_output=True, text=True, check=True,
    ).stdout
    result = json.loads(output.strip().splitlines()[-1])
    if not result["module"].startswith(str(checkout.resolve())):
        raise RuntimeError(f"{checkout} imported lerax_like from {result['module']}")
    return result


def main(argv=None) -> None:
    parser = benchmark_parser(__doc__, quick="2 rounds of 2 blocks")
    parser.add_argument("--old", type=Path, default=None, help="the old checkout (default: a worktree of --old-commit)")
    parser.add_argument("--old-commit", default="c47eebd")
    parser.add_argument("--new", type=Path, default=Path(__file__).resolve().parent.parent)
    parser.add_argument("--rounds", type=int, default=None, help="4 (2 with --quick)")
    parser.add_argument("--blocks", type=int, default=None, help="timed blocks per configuration and process: 5 (2)")
    args = parser.parse_args(argv)
    args.rounds = args.rounds or (2 if args.quick else 4)
    args.blocks = args.blocks or (2 if args.quick else 5)
    if args.old is not None:
        compare(args)
        return
    with tempfile.TemporaryDirectory() as folder:
        args.old = Path(folder) / "old"
        subprocess.run(["git", "worktree", "add", "--detach", str(args.old), args.old_commit], cwd=args.new, check=True)
        try:
            compare(args)
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(args.old)], cwd=args.new, check=True)


def compare(args) -> None:
    checkouts = {"old": args.old.resolve(), "new": args.new.resolve()}
    commits = {
        name: subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=path, capture_output=True, text=True).stdout.strip()
        for name, path in checkouts.items()
    }
    load_before = os.getloadavg()
    best = {name: [{"wall": float("inf"), "cpu": float("inf")} for _ in CONFIGS] for name in checkouts}
    for round_index in range(args.rounds):
        order = ("old", "new") if round_index % 2 == 0 else ("new", "old")
        for name in order:
            result = run_worker(checkouts[name], args.blocks)
            for config_best, timings in zip(best[name], result["results"], strict=True):
                config_best["wall"] = min(config_best["wall"], *timings["wall"])
                config_best["cpu"] = min(config_best["cpu"], *timings["cpu"])
            print(f"round {round_index} {name} done (load {os.getloadavg()[0]:.1f})", flush=True)
    date = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M")
    rows = []
    for index, (kind, env_id, num_envs, steps) in enumerate(CONFIGS):
        old, new = best["old"][index], best["new"][index]
        row = {
            "front_end": "gymnasium make_vec" if kind == "vector" else "lerax_like.sb3.make_vec_env",
            "id": env_id,
            "num_envs": num_envs,
            "old_commit": commits["old"],
            "new_commit": commits["new"],
            "old_steps_per_s": round(num_envs * steps / old["wall"]),
            "new_steps_per_s": round(num_envs * steps / new["wall"]),
            "new_vs_old": round(old["wall"] / new["wall"], 3),
            "new_vs_old_cpu_time": round(old["cpu"] / new["cpu"], 3),
            "steps_per_block": steps,
            "blocks": args.blocks * args.rounds,
            "rounds": args.rounds,
            "load_average_before": round(load_before[0], 1),
            "load_average_after": round(os.getloadavg()[0], 1),
            "date_utc": date,
            "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores",
        }
        rows.append(row)
        print(", ".join(f"{key}={value}" for key, value in row.items()), flush=True)
    write(rows, output_folder(args) / "gym_before_after.csv")

if __name__ == "__main__":
    main()
