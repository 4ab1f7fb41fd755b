"""PPO on `lerax_like.sb3.make_vec_env` against PPO on SB3's own `make_vec_env`, in one run.

    python -m benchmarks sb3_vector            # 40k steps, two rounds (ABBA order)
    python -m benchmarks sb3_vector --quick    # 4k steps, one round

The issue's recipe: PPO (`MlpPolicy`, seed 0, `n_steps=256`, other settings SB3's defaults,
CPU) on `make_vec_env("lerax_like/CartPole-v1", n_envs=8, seed=0)` and on SB3's
`make_vec_env("CartPole-v1", n_envs=8, seed=0)` (a `DummyVecEnv` of Gymnasium's numpy
CartPole), 40k steps each. Both trained policies are evaluated on Gymnasium's own env
(20 episodes, deterministic actions, the same evaluation seeds). The training runs go in
ABBA order, so that a drift of the machine's load hits both alike; each one's wall time is
kept, and the ratios use the fastest run of each. PyTorch runs on one thread (the machine
is shared; the same for both).

Beside it, the env alone: steps per second of random actions through each `VecEnv`
(`step_async`/`step_wait`, SB3's infos, autoreset) at n_envs = 8 and 256.
Writes sb3_vector.json under `--out` (default benchmarks/results, or results/quick with --quick).
"""

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import gymnasium
import numpy as np

import lerax_like
import lerax_like.sb3
from benchmarks import results_dir


def make(kind: str, n_envs: int, seed: int):
    from stable_baselines3.common.env_util import make_vec_env

    if kind == "lerax_like":
        return lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=n_envs, seed=seed)
    return make_vec_env("CartPole-v1", n_envs=n_envs, seed=seed)


def train(kind: str, total_timesteps: int) -> dict:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    start = time.perf_counter()
    venv = make(kind, 8, 0)
    model = PPO("MlpPolicy", venv, seed=0, n_steps=256, device="cpu", verbose=0)
    model.learn(total_timesteps=total_timesteps)
    seconds = time.perf_counter() - start
    evaluation = make_vec_env("CartPole-v1", n_envs=1, seed=1000)  # Gymnasium's env
    returns, _ = evaluate_policy(model, evaluation, n_eval_episodes=20, deterministic=True, return_episode_rewards=True)
    return {"seconds": seconds, "mean_return": float(np.mean(returns)), "returns": [float(r) for r in returns]}


def env_throughput(kind: str, n_envs: int, steps: int, repeats: int) -> float:
    venv = make(kind, n_envs, 0)
    venv.reset()
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 2, size=(steps, n_envs))
    for action in actions[:10]:
        venv.step(action)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for action in actions:
            venv.step(action)
        best = min(best, time.perf_counter() - start)
    venv.close()
    return n_envs * steps / best


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--timesteps", type=int, default=None)
    parser.add_argument("--out", type=Path, default=None, help="folder (default: benchmarks/results[/quick])")
    args = parser.parse_args(argv)
    timesteps = args.timesteps or (4_000 if args.quick else 40_000)
    order = ["gymnasium", "lerax_like"] if args.quick else ["gymnasium", "lerax_like", "lerax_like", "gymnasium"]
    output = (args.out or results_dir(args.quick)) / "sb3_vector.json"

    import stable_baselines3
    import torch

    torch.set_num_threads(1)
    load_before = os.getloadavg()
    runs = {"gymnasium": [], "lerax_like": []}
    for kind in order:
        run = train(kind, timesteps)
        runs[kind].append(run)
        print(f"{kind:10s} {timesteps} steps in {run['seconds']:.1f} s, mean return {run['mean_return']:.1f} "
              f"(load {os.getloadavg()[0]:.1f})", flush=True)

    throughput = {}
    for n_envs in (8, 256):
        steps = 400 if n_envs == 8 else 40
        for kind in ("gymnasium", "lerax_like"):
            throughput[f"{kind}_n{n_envs}"] = round(env_throughput(kind, n_envs, steps, 3 if args.quick else 7))
        print(f"env steps/s at n_envs={n_envs}: SB3 DummyVecEnv {throughput[f'gymnasium_n{n_envs}']}, "
              f"lerax_like {throughput[f'lerax_like_n{n_envs}']}", flush=True)

    fastest = {kind: min(run["seconds"] for run in kind_runs) for kind, kind_runs in runs.items()}
    # PPO with seed 0 is deterministic on a CPU: every run of a kind learns the same policy.
    returns = {kind: kind_runs[0]["mean_return"] for kind, kind_runs in runs.items()}
    result = {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores",
        "load_average_before": [round(x, 1) for x in load_before],
        "load_average_after": [round(x, 1) for x in os.getloadavg()],
        "versions": {"stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__,
                     "gymnasium": gymnasium.__version__, "lerax_like": lerax_like.__version__},
        "recipe": {"algorithm": "PPO", "policy": "MlpPolicy", "seed": 0, "n_steps": 256, "n_envs": 8,
                   "total_timesteps": timesteps, "device": "cpu", "torch_threads": 1,
                   "evaluation": "20 episodes of Gymnasium's CartPole-v1, deterministic, seed 1000"},
        "order": order,
        "runs": runs,
        "fastest_seconds": fastest,
        "mean_return": returns,
        "return_ratio_lerax_like_vs_sb3": round(returns["lerax_like"] / returns["gymnasium"], 3),
        "wall_time_ratio_lerax_like_vs_sb3": round(fastest["lerax_like"] / fastest["gymnasium"], 3),
        "env_steps_per_s": throughput,
        "env_speedup_n8": round(throughput["lerax_like_n8"] / throughput["gymnasium_n8"], 2),
        "env_speedup_n256": round(throughput["lerax_like_n256"] / throughput["gymnasium_n256"], 2),
    }
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({key: result[key] for key in ("mean_return", "fastest_seconds", "return_ratio_lerax_like_vs_sb3",
                                                    "wall_time_ratio_lerax_like_vs_sb3", "env_speedup_n8",
                                                    "env_speedup_n256", "load_average_after")}))
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
