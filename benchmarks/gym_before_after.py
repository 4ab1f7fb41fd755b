"""Throughput of the vector env and the SB3 VecEnv, two versions of the package interleaved in one run.

    python -m benchmarks.gym_before_after --old /tmp/old [--new .] [--rounds 6] [--out DIR]

`--old` and `--new` are checkouts (e.g. `git worktree add /tmp/old c47eebd`). Each round
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

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

from benchmarks import results_dir
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
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--old", type=Path, required=True)
    parser.add_argument("--new", type=Path, default=Path("."))
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--blocks", type=int, default=5, help="timed blocks per configuration and process")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
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
    write(rows, (args.out or results_dir(False)) / "gym_before_after.csv")

if __name__ == "__main__":
    main()
