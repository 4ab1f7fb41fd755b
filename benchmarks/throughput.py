"""Steps per second against the number of envs N: lerax_like CartPole beside its peers, in one run.

Workload (`_workload.py`): N CartPoles, random actions, autoreset, T steps in one jitted
`lax.scan`, vmapped over N; for the JAX envs the full `step` with autoreset:
- lerax_like `CartPole` with Euler, RK4 (both one fixed step per env step) and Tsit5
  (adaptive, `PIDController(rtol=1e-6, atol=1e-9)`);
- gymnax `CartPole-v1`;
- Gymnasium's numpy vector CartPole (`make_vec(..., vectorization_mode="vector_entry_point")`)
  and `SyncVectorEnv` (`vectorization_mode="sync"`, small N only), T steps of a Python loop
  with numpy random actions.
Repeats are interleaved across implementations for each N, so that the noise of a shared
machine falls on all of them alike; ratios are taken of the minima.

    python -m benchmarks throughput            # N = 1, 64, 1024, 16384; T = 500
    python -m benchmarks throughput --quick    # N = 1, 64; T = 100; a smoke test
    python -m benchmarks.throughput --envs 1024 16384 --repeats 7 --out DIR

Writes throughput.csv and throughput.png into benchmarks/results/ (results/quick/ with --quick).
"""

import argparse
import os
import pathlib
import platform

import jax
import jax.random as jr
import numpy as np

import lerax_like
from benchmarks import results_dir, write_csv
from benchmarks._workload import batched, compile_seconds, gymnax_program, interleaved, scanned, summary


SYNC_MAX_ENVS = 64


def lerax_program(solver: str):
    env = lerax_like.make("CartPole", solver=solver)

    def initial(key):
        return env.reset(key=key)[0]

    def step(state, action, key):
        state, _, reward, _, _, _ = env.step(state, action, key=key)
        return state, reward

    return step, initial


def gymnasium_runner(num_envs: int, num_steps: int, mode: str):
    import gymnasium

    envs = gymnasium.make_vec("CartPole-v1", num_envs=num_envs, vectorization_mode=mode)
    envs.reset(seed=0)
    rng = np.random.default_rng(0)

    def run():
        total = 0.0
        for _ in range(num_steps):
            _, reward, _, _, _ = envs.step(rng.integers(0, 2, num_envs))
            total += float(reward.sum())
        return total

    return run


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="N = 1, 64; T = 100; 2 repeats")
    parser.add_argument("--envs", type=int, nargs="+", default=None)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    env_counts = args.envs or ([1, 64] if args.quick else [1, 64, 1024, 16384])
    num_steps = args.steps or (100 if args.quick else 500)
    repeats = args.repeats or (2 if args.quick else 5)
    out.mkdir(parents=True, exist_ok=True)

    jax_programs = {
        "lerax_like Euler": lambda: lerax_program("euler"),
        "lerax_like RK4": lambda: lerax_program("rk4"),
        "lerax_like Tsit5": lambda: lerax_program("tsit5"),
        "gymnax": gymnax_program,
    }
    print(f"jax {jax.__version__} on {jax.devices()[0].platform}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()}; T={num_steps}, {repeats} interleaved repeats")
    rows = []
    for num_envs in env_counts:
        candidates, compile_times = {}, {}
        for name, make in jax_programs.items():
            step, initial = make()
            run = batched(scanned(step, initial, num_steps), num_envs)
            key = jr.key(0)
            compile_times[name], compiled = compile_seconds(run, key)
            jax.block_until_ready(compiled(key))
            candidates[name] = lambda compiled=compiled, key=key: jax.block_until_ready(compiled(key))
        modes = {"Gymnasium vector (numpy)": "vector_entry_point"}
        if num_envs <= SYNC_MAX_ENVS:
            modes["Gymnasium SyncVectorEnv"] = "sync"
        for name, mode in modes.items():
            candidates[name] = gymnasium_runner(num_envs, num_steps, mode)
            candidates[name]()
        # Small batches are quick and noisier: more repeats.
        times = interleaved(candidates, repeats if num_envs >= 1024 else 3 * repeats)
        gymnax_best = summary(times["gymnax"])[0]
        for name, seconds in times.items():
            best, median = summary(seconds)
            row = {
                "implementation": name,
                "num_envs": num_envs,
                "steps": num_steps,
                "min_s": best,
                "median_s": median,
                "steps_per_s": num_envs * num_steps / best,
                "speed_vs_gymnax": gymnax_best / best,
                "compile_s": compile_times.get(name, float("nan")),
            }
            rows.append(row)
            print(f"N={num_envs:6d} {name:26s} {row['steps_per_s'] / 1e6:9.3f} M steps/s "
                  f"(median {num_envs * num_steps / median / 1e6:8.3f})  x{row['speed_vs_gymnax']:6.2f} gymnax  "
                  f"compile {row['compile_s']:.2f} s", flush=True)
    print(f"load average at the end {os.getloadavg()}")

    write_csv(out / "throughput.csv", rows)
    plot(rows, out / "throughput.png", num_steps)


def plot(rows, path, num_steps):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed (pip install 'lerax_like[study]'); no plot written")
        return
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for name in dict.fromkeys(row["implementation"] for row in rows):
        points = [(row["num_envs"], row["steps_per_s"]) for row in rows if row["implementation"] == name]
        axes.plot(*zip(*points), marker="o", label=name)
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("number of envs N")
    axes.set_ylabel("env steps per second")
    axes.set_title(f"CartPole, random actions, autoreset, {num_steps} steps per call ({platform.machine()} CPU)")
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
