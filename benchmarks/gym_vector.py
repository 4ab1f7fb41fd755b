"""Steps per second of the vector env against Gymnasium's own vector CartPole, in one run.

    python benchmarks/gym_vector.py [--num-envs 1024] [--steps 200] [--repeats 7]

Both envs step the same pre-drawn random actions (episodes end every ~20 steps, so the
restart path is timed too). Each env is compiled/warmed first; the repeats alternate
between the two envs, so that load on the machine hits both alike; the median is kept.
Writes benchmarks/results/gym_vector.csv.
"""

import argparse
import csv
import datetime
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import gymnasium
import jax
import numpy as np


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import lerax_like  # noqa: E402  (registers the lerax_like/ ids)


def make(env_id: str, num_envs: int):
    return gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")


def time_steps(env, actions) -> float:
    start = time.perf_counter()
    for action in actions:
        env.step(action)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--output", default=str(Path(__file__).parent / "results" / "gym_vector.csv"))
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    actions = rng.integers(0, 2, size=(args.steps, args.num_envs))
    envs = {
        "lerax_like/CartPole-v1": make("lerax_like/CartPole-v1", args.num_envs),
        "CartPole-v1": make("CartPole-v1", args.num_envs),
    }
    for env in envs.values():
        env.reset(seed=0)
        time_steps(env, actions[:20])  # warm-up (ours is compiled at construction)
    times = {name: [] for name in envs}
    for _ in range(args.repeats):
        for name, env in envs.items():
            times[name].append(time_steps(env, actions))
    rates = {name: args.num_envs * args.steps / statistics.median(t) for name, t in times.items()}
    ratio = rates["lerax_like/CartPole-v1"] / rates["CartPole-v1"]

    machine = f"{platform.machine()} {platform.processor() or platform.system()}, {os.cpu_count()} cores"
    row = {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "machine": machine,
        "jax_backend": jax.default_backend(),
        "jax": jax.__version__,
        "gymnasium": gymnasium.__version__,
        "num_envs": args.num_envs,
        "steps_per_repeat": args.steps,
        "repeats": args.repeats,
        "lerax_like_steps_per_s": round(rates["lerax_like/CartPole-v1"]),
        "gymnasium_steps_per_s": round(rates["CartPole-v1"]),
        "ratio": round(ratio, 3),
        "lerax_like_min_s": round(min(times["lerax_like/CartPole-v1"]), 5),
        "gymnasium_min_s": round(min(times["CartPole-v1"]), 5),
    }
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    with output.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(row))
        writer.writeheader()
        writer.writerow(row)
    for key, value in row.items():
        print(f"{key}: {value}")


if __name__ == "__main__":
    main()
