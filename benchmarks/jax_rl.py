"""rejax's PPO on gymnax's CartPole and on lerax_like's (euler, rk4, tsit5): training time and final return.

    python -m benchmarks jax_rl            # rejax's CartPole config, 8 seeds vmapped, 3 interleaved rounds
    python -m benchmarks jax_rl --quick    # 10k steps, 2 seeds, 1 round (a smoke run)

A pure-JAX trainer as its users run it: rejax's PPO with its own CartPole-v1 configuration
(`benchmarks._workload.REJAX_CARTPOLE_PPO`: 100k steps, 5 envs, evaluation of 128 episodes
every 1000 steps), `jax.jit(jax.vmap(algorithm.train))` over the seeds, on gymnax's
`CartPole-v1` and on `lerax_like.gymnax.make("CartPole-v1", solver=...)`, float32 (JAX's
default, as gymnax and rejax use). Every candidate is compiled first; then the rounds run the
candidates one after another (interleaved, so that a drift of the machine's load hits all
alike), and the ratios use each candidate's fastest round (medians beside). The time of a
round is `train` as configured, rejax's periodic evaluations included (they step the env
too). The final return is the mean over the 128 episodes of rejax's last evaluation, then
mean and standard deviation over the seeds (the same seeds for every candidate).

Writes jax_rl.csv and jax_rl.json under `--out` (default benchmarks/results, or results/quick).
"""

import os
import statistics
import time

import jax
import numpy as np

from benchmarks import benchmark_parser, output_folder
from benchmarks._workload import REJAX_CARTPOLE_PPO, cartpole_env, compile_seconds, rejax_ppo_training
from lerax_like.analysis.recording import write_csv, write_record


CANDIDATES = {"gymnax": None, "euler": "euler", "rk4": "rk4", "tsit5": "tsit5"}


def main(argv=None) -> None:
    parser = benchmark_parser(__doc__, quick="10k steps, 2 seeds, 1 round")
    parser.add_argument("--seeds", type=int, default=None, help="seeds vmapped in one training call (default 8)")
    parser.add_argument("--rounds", type=int, default=None, help="interleaved timing rounds (default 3)")
    args = parser.parse_args(argv)
    seeds = args.seeds or (2 if args.quick else 8)
    rounds = args.rounds or (1 if args.quick else 3)
    overrides = {"total_timesteps": 10_000} if args.quick else {}
    out = output_folder(args)

    load_before = os.getloadavg()
    compiled, keys, compile_s, final = {}, None, {}, {}
    for name, solver in CANDIDATES.items():
        env, params = cartpole_env(solver)
        train, keys = rejax_ppo_training(env, params, seeds, **overrides)
        compile_s[name], compiled[name] = compile_seconds(train, keys)
        print(f"{name:7s} compiled in {compile_s[name]:.1f} s (load {os.getloadavg()[0]:.1f})", flush=True)

    seconds = {name: [] for name in CANDIDATES}
    for round_index in range(rounds):
        for name in CANDIDATES:
            start = time.perf_counter()
            _, (_, returns) = jax.block_until_ready(compiled[name](keys))
            seconds[name].append(time.perf_counter() - start)
            # The same program on the same keys gives the same returns every round.
            final[name] = np.asarray(returns)[:, -1, :].mean(axis=-1)
            print(f"round {round_index + 1}: {name:7s} {seconds[name][-1]:.2f} s, final return "
                  f"{final[name].mean():.1f} +- {final[name].std():.1f} (load {os.getloadavg()[0]:.1f})", flush=True)

    load_after = os.getloadavg()
    fastest = {name: min(times) for name, times in seconds.items()}
    median = {name: statistics.median(times) for name, times in seconds.items()}
    rows = []
    for name, solver in CANDIDATES.items():
        rows.append({
            "env": "gymnax CartPole-v1" if solver is None else f"lerax_like CartPole-v1 ({solver})",
            "solver": solver or "",
            "compile_s": round(compile_s[name], 2),
            "fastest_s": round(fastest[name], 3),
            "median_s": round(median[name], 3),
            "time_ratio_fastest": round(fastest[name] / fastest["gymnax"], 3),
            "time_ratio_median": round(median[name] / median["gymnax"], 3),
            "final_return_mean": round(float(final[name].mean()), 1),
            "final_return_std": round(float(final[name].std()), 1),
            "return_ratio": round(float(final[name].mean() / final["gymnax"].mean()), 3),
        })
        print(f"{rows[-1]['env']:34s} time {rows[-1]['time_ratio_fastest']:.2f}x gymnax's (fastest), "
              f"{rows[-1]['time_ratio_median']:.2f}x (median); final return {rows[-1]['final_return_mean']} "
              f"+- {rows[-1]['final_return_std']}", flush=True)
    write_csv(rows, out / "jax_rl.csv")
    record = {
        "recipe": {**REJAX_CARTPOLE_PPO, **overrides, "seeds": seeds, "rounds": rounds, "precision": "float32"},
        "seconds": {name: [round(value, 3) for value in times] for name, times in seconds.items()},
        "final_return_per_seed": {name: [round(float(value), 1) for value in returns] for name, returns in final.items()},
        "load_average_before": [round(value, 2) for value in load_before],
        "load_average_after": [round(value, 2) for value in load_after],
    }
    write_record(record, out / "jax_rl.json")
    print(f"wrote {out / 'jax_rl.csv'} and {out / 'jax_rl.json'}")


if __name__ == "__main__":
    main()
