"""Steps per second of the vector env against Gymnasium's own vector CartPole, in one run.

    python benchmarks/gym_vector.py [--num-envs 1024 16384] [--steps 100] [--repeats 15]

Both envs step the same pre-drawn random actions (episodes end every ~20 steps, so the
restart path is timed too). Each env is compiled/warmed first; the repeats alternate
between the two envs, so that load on the machine hits both alike; the median is kept.
Writes benchmarks/results/gym_vector.csv, one row per number of envs (1024 is the one the
issue asks for; a larger one shows where the fixed cost per call stops mattering).
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, nargs="+", default=[1024, 16384])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--output", default=str(Path(__file__).parent / "results" / "gym_vector.csv"))
    args = parser.parse_args()

    rows = [measure(num_envs, args.steps, args.repeats) for num_envs in args.num_envs]
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    with output.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    for row in rows:
        print(", ".join(f"{key}={value}" for key, value in row.items()))


if __name__ == "__main__":
    main()
