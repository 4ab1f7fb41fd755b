"""A CleanRL-shaped loop: Gymnasium's `SyncVectorEnv` of four single envs, ours against Gymnasium's CartPole.

    python -m benchmarks cleanrl_loop            # 50k env steps, 3 interleaved rounds
    python -m benchmarks cleanrl_loop --quick    # 4k env steps, 1 round

CleanRL's `ppo.py` builds `gymnasium.vector.SyncVectorEnv([make_env(...) for i in range(4)])`
over `gymnasium.make(env_id)` and steps it from Python. Here the policy is a random action
(NumPy, seed 0), so what is timed is the env path alone: 50k env steps (12,500 steps of the
4-env vector), `gymnasium.make("lerax_like/CartPole-v1")` against `gymnasium.make("CartPole-v1")`.

Each run is a fresh process (import and compile are paid per process, as a user pays them),
and its cost is split into
- import: `import gymnasium` (and `import lerax_like`, which imports JAX, for ours);
- setup: `SyncVectorEnv(...)`, `reset(seed=0)` and the first step: for ours this holds JAX's
  tracing and XLA's compile of the step, recorded apart from JAX's own compile events
  (`jax.monitoring`: tracing, lowering, backend compile);
- step: the mean time of one 4-env vector step over the rest.

JAX's persistent compilation cache is measured too: `lerax_like` with the cache in an empty
folder (the first process on a machine: compiles and writes) and again in that folder (every
later process: reads), with `jax_persistent_cache_min_compile_time_secs` at 0 (JAX's default
of 1 s would skip a step that compiles in less). Rounds interleave the four kinds, the order
reversed every other round, so that a drift of the machine's load hits each alike; a kind's
figures are the median over rounds. Writes cleanrl_loop.csv and cleanrl_loop.json.
"""

import argparse
import csv
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

from benchmarks import benchmark_parser, output_folder


ENV_IDS = {"gymnasium": "CartPole-v1", "lerax_like": "lerax_like/CartPole-v1"}
# kind: (env, cache): the cache folder is fresh for "cache_cold" and reused by "cache_warm".
KINDS = {
    "gymnasium": ("gymnasium", None),
    "lerax_like": ("lerax_like", None),
    "lerax_like_cache_cold": ("lerax_like", "cold"),
    "lerax_like_cache_warm": ("lerax_like", "warm"),
}
NUM_ENVS = 4
COMPILE_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace_s",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower_s",
    "/jax/core/compile/backend_compile_duration": "backend_compile_s",
}


def child(env: str, env_steps: int, cache: str | None) -> dict:
    """One process's run; returns its figures (printed as JSON by `--child`)."""
    started = time.perf_counter()
    import gymnasium
    import numpy as np

    if env == "lerax_like":
        import jax

        import lerax_like  # noqa: F401  (registers the ids)

        if cache is not None:
            jax.config.update("jax_compilation_cache_dir", cache)
            jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        compile_times = dict.fromkeys(COMPILE_EVENTS.values(), 0.0)

        def listen(event, duration, **_):
            if event in COMPILE_EVENTS:
                compile_times[COMPILE_EVENTS[event]] += duration

        jax.monitoring.register_event_duration_secs_listener(listen)
    imported = time.perf_counter()

    envs = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(ENV_IDS[env]) for _ in range(NUM_ENVS)])
    rng = np.random.default_rng(0)
    actions = rng.integers(0, 2, size=(env_steps // NUM_ENVS, NUM_ENVS))
    envs.reset(seed=0)
    envs.step(actions[0])
    set_up = time.perf_counter()
    for action in actions[1:]:
        envs.step(action)
    stepped = time.perf_counter()
    envs.close()
    result = {
        "import_s": imported - started,
        "setup_s": set_up - imported,
        "step_us": (stepped - set_up) / (len(actions) - 1) * 1e6,
        "loop_s": stepped - started,
    }
    if env == "lerax_like":
        result.update(compile_times)
    return result


def run_child(kind: str, env_steps: int, cache_folder: pathlib.Path) -> dict:
    env, cache = KINDS[kind]
    arguments = [sys.executable, "-m", "benchmarks.cleanrl_loop", "--child", env, "--env-steps", str(env_steps)]
    if cache is not None:
        arguments += ["--cache", str(cache_folder)]
    started = time.perf_counter()
    completed = subprocess.run(arguments, capture_output=True, text=True, check=True,
                               cwd=pathlib.Path(__file__).resolve().parent.parent)
    result = json.loads(completed.stdout.strip().splitlines()[-1])
    result["process_s"] = time.perf_counter() - started  # interpreter start and exit included
    return result


def main(argv=None) -> None:
    parser = benchmark_parser(__doc__, quick="4k env steps, 1 round")
    parser.add_argument("--env-steps", type=int, default=None)
    parser.add_argument("--rounds", type=int, default=None)
    parser.add_argument("--child", choices=sorted(ENV_IDS), default=None, help=argparse.SUPPRESS)
    parser.add_argument("--cache", default=None, help=argparse.SUPPRESS)
    arguments = parser.parse_args(argv)
    env_steps = arguments.env_steps or (4_000 if arguments.quick else 50_000)
    if arguments.child:
        print(json.dumps(child(arguments.child, env_steps, arguments.cache)))
        return
    rounds = arguments.rounds or (1 if arguments.quick else 3)
    load_before = os.getloadavg()
    runs = {kind: [] for kind in KINDS}
    for round_index in range(rounds):
        # A fresh cache each round: "cold" is the first process on a machine, "warm" the next.
        with tempfile.TemporaryDirectory(prefix="jax_cache_") as cache_folder:
            order = list(KINDS) if round_index % 2 == 0 else [
                "lerax_like", "gymnasium", "lerax_like_cache_cold", "lerax_like_cache_warm"
            ]  # cold before warm in every round: the warm run reads what the cold one wrote
            for kind in order:
                result = run_child(kind, env_steps, pathlib.Path(cache_folder))
                runs[kind].append(result)
                print(f"round {round_index} {kind:22s} " + ", ".join(f"{k} {v:.4g}" for k, v in result.items())
                      + f" (load {os.getloadavg()[0]:.1f})", flush=True)

    medians = {kind: {name: statistics.median(run[name] for run in kind_runs) for name in kind_runs[0]}
               for kind, kind_runs in runs.items()}
    gym = medians["gymnasium"]
    rows = []
    for kind, median in medians.items():
        rows.append({
            "kind": kind, "env_id": ENV_IDS[KINDS[kind][0]], "persistent_cache": KINDS[kind][1] or "off",
            **{name: round(value, 4) for name, value in median.items()},
            "step_ratio": round(median["step_us"] / gym["step_us"], 3),
            "process_ratio": round(median["process_s"] / gym["process_s"], 3),
        })
    out = output_folder(arguments)
    names = ["kind", "env_id", "persistent_cache", "import_s", "setup_s", "trace_s", "lower_s", "backend_compile_s",
             "step_us", "loop_s", "process_s", "step_ratio", "process_ratio"]
    with open(out / "cleanrl_loop.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=names, restval="")
        writer.writeheader()
        writer.writerows(rows)
    summary = {
        "recipe": {"num_envs": NUM_ENVS, "env_steps": env_steps, "rounds": rounds, "vector": "SyncVectorEnv",
                   "actions": "uniform random, NumPy seed 0"},
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "runs": runs,
    }
    (out / "cleanrl_loop.json").write_text(json.dumps(summary, indent=1) + "\n")
    for row in rows:
        print(row)


if __name__ == "__main__":
    main()
