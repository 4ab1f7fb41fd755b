"""Steps per second of the vector env against Gymnasium's own vector CartPole, in one run.

    python -m benchmarks gym_vector [--quick]
    python -m benchmarks.gym_vector [--num-envs 1024 16384] [--steps 100] [--repeats 15] [--out DIR]

Both envs step the same pre-drawn random actions (episodes end every ~20 steps, so the
restart path is timed too). Each env is compiled/warmed first; the repeats alternate
between the two envs, so that load on the machine hits both alike; the median is kept.
Writes gym_vector.csv into benchmarks/results/ (results/quick/ with --quick), one row per number of envs (1024 is the one the
issue asks for; a larger one shows where the fixed cost per call stops mattering).
"""

import argparse
import csv
import datetime
import os
import platform
import statistics
import time
from pathlib import Path

import gymnasium
import jax
import numpy as np

import lerax_like  # noqa: F401  (registers the lerax_like/ ids)
from benchmarks import results_dir


def make(env_id: str, num_envs: int):
    return gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")


def time_steps(env, actions) -> float:
    start = time.perf_counter()
    for action in actions:
        env.step(action)
    return time.perf_counter() - start


def measure(num_envs: int, steps: int, repeats: int) -> dict:
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 2, size=(steps, num_envs))
    envs = {
        "lerax_like/CartPole-v1": make("lerax_like/CartPole-v1", num_envs),
        "CartPole-v1": make("CartPole-v1", num_envs),
    }
    for env in envs.values():
        env.reset(seed=0)
        time_steps(env, actions[:20])  # warm-up (ours is compiled at construction)
    times = {name: [] for name in envs}
    for _ in range(repeats):
        for name, env in envs.items():
            times[name].append(time_steps(env, actions))
    rates = {name: num_envs * steps / statistics.median(t) for name, t in times.items()}
    best = {name: num_envs * steps / min(t) for name, t in times.items()}
    machine = f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores"
    return {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "machine": machine,
        "load_average_1min": round(os.getloadavg()[0], 1),
        "jax_backend": jax.default_backend(),
        "jax": jax.__version__,
        "gymnasium": gymnasium.__version__,
        "num_envs": num_envs,
        "steps_per_repeat": steps,
        "repeats": repeats,
        "lerax_like_steps_per_s_median": round(rates["lerax_like/CartPole-v1"]),
        "gymnasium_steps_per_s_median": round(rates["CartPole-v1"]),
        "ratio_median": round(rates["lerax_like/CartPole-v1"] / rates["CartPole-v1"], 3),
        "lerax_like_steps_per_s_best": round(best["lerax_like/CartPole-v1"]),
        "gymnasium_steps_per_s_best": round(best["CartPole-v1"]),
        "ratio_best": round(best["lerax_like/CartPole-v1"] / best["CartPole-v1"], 3),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 64, 20 steps, 3 repeats")
    parser.add_argument("--num-envs", type=int, nargs="+", default=None)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--out", type=Path, default=None, help="default: benchmarks/results[/quick]")
    args = parser.parse_args(argv)
    num_envs = args.num_envs or ([64] if args.quick else [1024, 16384])
    steps = args.steps or (20 if args.quick else 100)
    repeats = args.repeats or (3 if args.quick else 15)

    rows = [measure(n, steps, repeats) for n in num_envs]
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    output = out / "gym_vector.csv"
    with output.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    for row in rows:
        print(", ".join(f"{key}={value}" for key, value in row.items()))


if __name__ == "__main__":
    main()
