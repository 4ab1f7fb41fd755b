"""PPO on `lerax_like.sb3.make_vec_env` against PPO on SB3's own `make_vec_env`, in interleaved rounds.

    python -m benchmarks sb3_vector            # 40k steps, 5 rounds
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
256. This process makes the VecEnvs as a user's script does, with `make_vec_env`'s default
`inline_dispatch=True` (JAX's CPU dispatch made inline: each computation runs in the
calling thread); a second process makes them with `inline_dispatch=False`, leaving JAX's
default asynchronous dispatch, and times PPO and the VecEnvs again, both kinds interleaved.
Writes sb3_vector.json under `--out` (default benchmarks/results, or results/quick with --quick).
"""

import argparse
import datetime
import gc
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


INLINE_DISPATCH = True
"""`make_vec_env`'s `inline_dispatch` (False in the process run with --async-dispatch)."""


def make(kind: str, n_envs: int, seed: int):
    from stable_baselines3.common.env_util import make_vec_env

    if kind == "lerax_like":
        return lerax_like.sb3.make_vec_env(
            "lerax_like/CartPole-v1", n_envs=n_envs, seed=seed, inline_dispatch=INLINE_DISPATCH
        )
    return make_vec_env("CartPole-v1", n_envs=n_envs, seed=seed)


def train(kind: str, total_timesteps: int) -> dict:
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    gc.collect()  # each run starts with no garbage of the runs before it
    start = time.perf_counter()
    venv = make(kind, 8, 0)
    made = time.perf_counter()
    stepping = [0.0, 0]  # seconds in the VecEnv's step, steps

    def timed_step(actions, step=venv.step):
        begun = time.perf_counter()
        result = step(actions)
        stepping[0] += time.perf_counter() - begun
        stepping[1] += 1
        return result

    venv.step = timed_step  # what PPO's rollouts call
    model = PPO("MlpPolicy", venv, seed=0, n_steps=256, device="cpu", verbose=0)
    model.learn(total_timesteps=total_timesteps)
    seconds = time.perf_counter() - start
    evaluation = make_vec_env("CartPole-v1", n_envs=1, seed=1000)  # Gymnasium's env
    returns, _ = evaluate_policy(model, evaluation, n_eval_episodes=20, deterministic=True, return_episode_rewards=True)
    return {"seconds": seconds, "make_seconds": made - start, "step_us": 1e6 * stepping[0] / stepping[1],
            "mean_return": float(np.mean(returns)), "returns": [float(r) for r in returns]}


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


def jax_dispatch() -> str:
    """JAX's CPU dispatch in this process, as its flag says (read once JAX's client has started)."""
    return "async" if jax.config.values["jax_cpu_enable_async_dispatch"] else "inline"


def async_child(*arguments: str) -> Any:
    """What this script prints last with `arguments`, run in a process of its own whose
    VecEnvs are made with `inline_dispatch=False` (JAX's default asynchronous dispatch)."""
    completed = subprocess.run(
        [sys.executable, "-m", "benchmarks.sb3_vector", "--async-dispatch", *arguments], capture_output=True,
        text=True, check=True, cwd=Path(__file__).resolve().parent.parent,
    )
    return json.loads(completed.stdout.strip().splitlines()[-1])


def _ratio(ours: list[float], theirs: list[float], pick) -> float:
    return round(pick(ours) / pick(theirs), 3)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--timesteps", type=int, default=None)
    parser.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 5, 1 with --quick)")
    parser.add_argument("--repeats", type=int, default=None, help="repeats of each env loop (fastest kept)")
    parser.add_argument("--throughput-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--train-only", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--async-dispatch", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=None, help="folder (default: benchmarks/results[/quick])")
    args = parser.parse_args(argv)
    rounds = args.rounds or (1 if args.quick else 5)
    repeats = args.repeats or (3 if args.quick else 5)
    global INLINE_DISPATCH
    INLINE_DISPATCH = not args.async_dispatch
    if args.throughput_only:
        speeds = throughputs(rounds, repeats)
        assert jax_dispatch() == "async", "the --async-dispatch process runs with JAX's dispatch inline"
        print(json.dumps(speeds))
        return
    timesteps = args.timesteps or (4_000 if args.quick else 40_000)
    order = [kind for index in range(rounds)
             for kind in (("gymnasium", "lerax_like") if index % 2 == 0 else ("lerax_like", "gymnasium"))]
    if args.train_only:
        import torch

        torch.set_num_threads(1)
        runs = {"gymnasium": [], "lerax_like": []}
        for kind in order:
            runs[kind].append(train(kind, timesteps))
        assert jax_dispatch() == "async", "the --async-dispatch process runs with JAX's dispatch inline"
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
        print(f"{kind:10s} {timesteps} steps in {run['seconds']:.1f} s (of which make_vec_env {run['make_seconds']:.2f} s, "
              f"VecEnv step {run['step_us']:.0f} us), mean return {run['mean_return']:.1f} "
              f"(load {os.getloadavg()[0]:.1f})", flush=True)

    # What `make_vec_env`'s default made of JAX's dispatch here (this process did no JAX work before).
    default_dispatch = jax_dispatch()
    if default_dispatch != "inline":
        raise SystemExit("make_vec_env left JAX's dispatch asynchronous: JAX had started before it (run in a fresh process)")
    async_runs = async_child("--train-only", "--rounds", str(rounds), "--timesteps", str(timesteps))
    for kind, kind_runs in async_runs.items():
        print(f"{kind:10s} {timesteps} steps in {min(run['seconds'] for run in kind_runs):.1f} s (fastest), "
              "inline_dispatch=False: JAX's asynchronous dispatch", flush=True)
    speeds = {
        default_dispatch: throughputs(rounds, repeats),
        "async": async_child("--throughput-only", "--rounds", str(rounds), "--repeats", str(repeats)),
    }
    for dispatch, by_kind in speeds.items():
        for n_envs in (8, 256):
            print(f"env steps/s at n_envs={n_envs}, {dispatch} dispatch: SB3 DummyVecEnv "
                  f"{max(by_kind[f'gymnasium_n{n_envs}']):.0f}, lerax_like {max(by_kind[f'lerax_like_n{n_envs}']):.0f}",
                  flush=True)
    throughput = {kind: round(max(values)) for kind, values in speeds[default_dispatch].items()}

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
        "default_dispatch": default_dispatch,
        "runs": runs,
        "fastest_seconds": fastest,
        "median_seconds": {kind: statistics.median(values) for kind, values in seconds.items()},
        # The VecEnv's `step` as PPO's rollouts call it, microseconds per call (median run).
        "median_step_us_in_ppo": {kind: round(statistics.median(run["step_us"] for run in kind_runs), 1)
                                  for kind, kind_runs in runs.items()},
        "mean_return": returns,
        "return_ratio_lerax_like_vs_sb3": round(returns["lerax_like"] / returns["gymnasium"], 3),
        "wall_time_ratio_lerax_like_vs_sb3": round(fastest["lerax_like"] / fastest["gymnasium"], 3),
        "async_dispatch_runs": async_runs,
        "async_wall_time_ratio_lerax_like_vs_sb3": _ratio(
            [run["seconds"] for run in async_runs["lerax_like"]], [run["seconds"] for run in async_runs["gymnasium"]], min
        ),
        "async_median_wall_time_ratio_lerax_like_vs_sb3": _ratio(
            [run["seconds"] for run in async_runs["lerax_like"]],
            [run["seconds"] for run in async_runs["gymnasium"]], statistics.median,
        ),
        "median_wall_time_ratio_lerax_like_vs_sb3": _ratio(seconds["lerax_like"], seconds["gymnasium"], statistics.median),
        # Each round's two runs side by side (the same stretch of the machine's load), then the median round.
        "paired_wall_time_ratios_lerax_like_vs_sb3": [
            round(ours / theirs, 3) for ours, theirs in zip(seconds["lerax_like"], seconds["gymnasium"])
        ],
        "median_paired_wall_time_ratio_lerax_like_vs_sb3": round(
            statistics.median(ours / theirs for ours, theirs in zip(seconds["lerax_like"], seconds["gymnasium"])), 3
        ),
        "env_steps_per_s": throughput,
        "env_steps_per_s_rounds": speeds,
        "env_speedup": speedups,
        "env_speedup_n8": speedups[f"{default_dispatch}_n8"]["fastest"],
        "env_speedup_n256": speedups[f"{default_dispatch}_n256"]["fastest"],
    }
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps({key: result[key] for key in ("mean_return", "fastest_seconds", "return_ratio_lerax_like_vs_sb3",
                                                    "wall_time_ratio_lerax_like_vs_sb3",
                                                    "median_wall_time_ratio_lerax_like_vs_sb3",
                                                    "median_paired_wall_time_ratio_lerax_like_vs_sb3",
                                                    "async_wall_time_ratio_lerax_like_vs_sb3",
                                                    "async_median_wall_time_ratio_lerax_like_vs_sb3", "env_speedup",
                                                    "load_average_after")}))
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
