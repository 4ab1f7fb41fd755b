"""PPO on `lerax_like.sb3.make_vec_env` against PPO on SB3's own `make_vec_env`, in interleaved rounds.

    python -m benchmarks sb3_vector            # 40k steps, 3 rounds
    python -m benchmarks sb3_vector --quick    # 4k steps, 1 round

The issue's recipe: PPO (`MlpPolicy`, seed 0, `n_steps=256`, other settings SB3's defaults,
CPU) on `make_vec_env("lerax_like/CartPole-v1", n_envs=8, seed=0)` and on SB3's
`make_vec_env("CartPole-v1", n_envs=8, seed=0)` (a `DummyVecEnv` of Gymnasium's numpy
CartPole), 40k steps each. Both trained policies are evaluated on Gymnasium's own env
(20 episodes, deterministic actions, the same evaluation seeds). Each round trains both, the
order reversed every other round (AB, BA, AB, ...), so that a drift of the machine's load
hits both alike; each run's wall time is kept, and the ratios are taken of the fastest and of
the median run of each. PyTorch runs on one thread (the machine is shared; the same for both).

Beside it, the env alone, interleaved the same way: steps per second of random actions
through each `VecEnv` (`step_async`/`step_wait`, SB3's infos, autoreset) at n_envs = 8 and
256, in this process (JAX's default asynchronous CPU dispatch) and in a second process with
`jax.config.update("jax_cpu_enable_async_dispatch", False)` set before lerax_like is imported
(each computation runs in the calling thread), where PPO is timed again, both kinds interleaved.
Writes sb3_vector.json under `--out` (default benchmarks/results, or results/quick with --quick).
"""

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from typing import Any
from pathlib import Path

import gymnasium
import jax
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


def throughputs(rounds: int, repeats: int) -> dict[str, list[float]]:
    """Env steps per second of each VecEnv, `rounds` interleaved rounds, by `KIND_n{n_envs}`."""
    speeds = {}
    for round_index in range(rounds):
        for n_envs in (8, 256):
            steps = 400 if n_envs == 8 else 40
            kinds = ("gymnasium", "lerax_like") if round_index % 2 == 0 else ("lerax_like", "gymnasium")
            for kind in kinds:
                speeds.setdefault(f"{kind}_n{n_envs}", []).append(env_throughput(kind, n_envs, steps, repeats))
    return speeds


# JAX reads `jax_cpu_enable_async_dispatch` when it starts its CPU client, and importing
# lerax_like starts it; JAX 0.10 does not read the flag from the environment
# (JAX_CPU_ENABLE_ASYNC_DISPATCH=false leaves it True). So the inline child sets it first.
_INLINE = ("import jax; jax.config.update('jax_cpu_enable_async_dispatch', False); import runpy; "
           "runpy.run_module('benchmarks.sb3_vector', run_name='__main__')")


def inline_child(*arguments: str) -> Any:
    """What this script prints last with `arguments`, run in a process of its own with JAX's
    CPU dispatch inline (each computation in the calling thread)."""
    completed = subprocess.run(
        [sys.executable, "-c", _INLINE, *arguments], capture_output=True, text=True, check=True,
        cwd=Path(__file__).resolve().parent.parent,
    )
    return json.loads(completed.stdout.strip().splitlines()[-1])


def _ratio(ours: list[float], theirs: list[float], pick) -> float:
    return round(pick(ours) / pick(theirs), 3)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--timesteps", type=int, default=None)
    parser.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 3, 1 with --quick)")
    parser.add_argument("--repeats", type=int, default=None, help="repeats of each env loop (fastest kept)")
    parser.add_argument("--throughput-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--train-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=None, help="folder (default: benchmarks/results[/quick])")
    args = parser.parse_args(argv)
    rounds = args.rounds or (1 if args.quick else 3)
    repeats = args.repeats or (3 if args.quick else 5)
    if args.throughput_only:
        print(json.dumps(throughputs(rounds, repeats)))
        return
    timesteps = args.timesteps or (4_000 if args.quick else 40_000)
    order = [kind for index in range(rounds)
             for kind in (("gymnasium", "lerax_like") if index % 2 == 0 else ("lerax_like", "gymnasium"))]
    if args.train_only:
        import torch

        torch.set_num_threads(1)
        assert not jax.config.values["jax_cpu_enable_async_dispatch"], "the inline child runs with async dispatch"
        runs = {"gymnasium": [], "lerax_like": []}
        for kind in order:
            runs[kind].append(train(kind, timesteps))
        print(json.dumps(runs))
        return
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

    inline_runs = inline_child("--train-only", "--rounds", str(rounds), "--timesteps", str(timesteps))
    for kind, kind_runs in inline_runs.items():
        print(f"{kind:10s} {timesteps} steps in {min(run['seconds'] for run in kind_runs):.1f} s (fastest), "
              "JAX's dispatch inline", flush=True)
    speeds = {
        "async": throughputs(rounds, repeats),
        "inline": inline_child("--throughput-only", "--rounds", str(rounds), "--repeats", str(repeats)),
    }
    for dispatch, by_kind in speeds.items():
        for n_envs in (8, 256):
            print(f"env steps/s at n_envs={n_envs}, {dispatch} dispatch: SB3 DummyVecEnv "
                  f"{max(by_kind[f'gymnasium_n{n_envs}']):.0f}, lerax_like {max(by_kind[f'lerax_like_n{n_envs}']):.0f}",
                  flush=True)
    throughput = {kind: round(max(values)) for kind, values in speeds["async"].items()}

    seconds = {kind: [run["seconds"] for run in kind_runs] for kind, kind_runs in runs.items()}
    fastest = {kind: min(values) for kind, values in seconds.items()}
    # PPO with seed 0 is deterministic on a CPU: every run of a kind learns the same policy.
    returns = {kind: kind_runs[0]["mean_return"] for kind, kind_runs in runs.items()}
    speedups = {
        f"{dispatch}_n{n_envs}": {
            "fastest": _ratio(by_kind[f"lerax_like_n{n_envs}"], by_kind[f"gymnasium_n{n_envs}"], max),
            "median": _ratio(by_kind[f"lerax_like_n{n_envs}"], by_kind[f"gymnasium_n{n_envs}"], statistics.median),
        }
        for dispatch, by_kind in speeds.items() for n_envs in (8, 256)
    }
    result = {
        "date_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M"),
        "machine": f"{platform.machine()} {platform.system()}, {os.cpu_count()} cores",
        "load_average_before": [round(x, 1) for x in load_before],
        "load_average_after": [round(x, 1) for x in os.getloadavg()],
        "versions": {"stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__,
                     "gymnasium": gymnasium.__version__, "lerax_like": lerax_like.__version__},
        "recipe": {"algorithm": "PPO", "policy": "MlpPolicy", "seed": 0, "n_steps": 256, "n_envs": 8,
                   "total_timesteps": timesteps, "device": "cpu", "torch_threads": 1, "rounds": rounds,
                   "evaluation": "20 episodes of Gymnasium's CartPole-v1, deterministic, seed 1000"},
        "order": order,
        "runs": runs,
        "fastest_seconds": fastest,
        "median_seconds": {kind: statistics.median(values) for kind, values in seconds.items()},
        "mean_return": returns,
        "return_ratio_lerax_like_vs_sb3": round(returns["lerax_like"] / returns["gymnasium"], 3),
        "wall_time_ratio_lerax_like_vs_sb3": round(fastest["lerax_like"] / fastest["gymnasium"], 3),
        "inline_dispatch_runs": inline_runs,
        "inline_wall_time_ratio_lerax_like_vs_sb3": _ratio(
            [run["seconds"] for run in inline_runs["lerax_like"]], [run["seconds"] for run in inline_runs["gymnasium"]], min
        ),
        "inline_median_wall_time_ratio_lerax_like_vs_sb3": _ratio(
            [run["seconds"] for run in inline_runs["lerax_like"]],
            [run["seconds"] for run in inline_runs["gymnasium"]], statistics.median,
        ),
        "median_wall_time_ratio_lerax_like_vs_sb3": _ratio(seconds["lerax_like"], seconds["gymnasium"], statistics.median),
        "env_steps_per_s": throughput,
        "env_steps_per_s_rounds": speeds,
        "env_speedup": speedups,
        "env_speedup_n8": speedups["async_n8"]["fastest"],
        "env_speedup_n256": speedups["async_n256"]["fastest"],
    }
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({key: result[key] for key in ("mean_return", "fastest_seconds", "return_ratio_lerax_like_vs_sb3",
                                                    "wall_time_ratio_lerax_like_vs_sb3",
                                                    "median_wall_time_ratio_lerax_like_vs_sb3",
                                                    "inline_wall_time_ratio_lerax_like_vs_sb3",
                                                    "inline_median_wall_time_ratio_lerax_like_vs_sb3", "env_speedup",
                                                    "load_average_after")}))
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
