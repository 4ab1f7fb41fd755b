"""Compile time of a 1000-step scanned rollout, per solver, beside gymnax.

Two programs per solver, each a fresh `jax.jit` (new closures, so no cache is hit):
- `rollout`: `lerax_like.rollout` (transition only) of one env over 1000 actions;
- `step`: the throughput workload (`_workload.py`) of 1000 `env.step` calls with autoreset
  and random actions, vmapped over N=1024 envs.
Reported: trace + lowering and XLA compilation, in wall-clock seconds and in CPU seconds of
this process (less sensitive to other processes on a shared machine; compilation is
mostly single-threaded), minimum over fresh repeats.

    python -m benchmarks compile_time
    python -m benchmarks compile_time --quick     # Euler only, 100 steps, N=64, one compile
    python -m benchmarks.compile_time --repeats 1 --solvers euler rk4 --out DIR

Writes compile_time.csv into benchmarks/results/ (results/quick/ with --quick).
"""

import os
import time

import jax
import jax.numpy as jnp
import jax.random as jr

import lerax_like
from benchmarks import benchmark_parser, output_folder
from benchmarks._workload import batched, gymnax_program, scanned
from lerax_like.analysis.recording import write_csv
from benchmarks.throughput import lerax_program


NUM_STEPS = 1000
NUM_ENVS = 1024


def measure(make_jitted, args) -> dict[str, float]:
    """Seconds to trace + lower and to compile a fresh jitted function, wall and CPU."""
    jitted = make_jitted()
    wall, cpu = time.perf_counter(), time.process_time()
    lowered = jitted.lower(*args)
    wall_lower, cpu_lower = time.perf_counter() - wall, time.process_time() - cpu
    wall, cpu = time.perf_counter(), time.process_time()
    lowered.compile()
    wall_compile, cpu_compile = time.perf_counter() - wall, time.process_time() - cpu
    return {
        "lower_wall_s": wall_lower,
        "compile_wall_s": wall_compile,
        "total_wall_s": wall_lower + wall_compile,
        "total_cpu_s": cpu_lower + cpu_compile,
    }


def rollout_program(solver, num_steps=NUM_STEPS):
    def make():
        env = lerax_like.make("CartPoleContinuous", solver=solver)

        @jax.jit
        def run(y0, actions, key):
            state = lerax_like.EnvState(y=y0, steps=jnp.zeros((), dtype=int))
            return lerax_like.rollout(env, state, actions, key=key)

        return run

    return make, (jnp.zeros(4), jnp.zeros((num_steps, 1)), jr.key(0))


def step_program(make_step, num_steps=NUM_STEPS, num_envs=NUM_ENVS):
    def make():
        step, initial = make_step()
        return batched(scanned(step, initial, num_steps), num_envs)

    return make, (jr.key(0),)


def main(argv=None):
    parser = benchmark_parser(__doc__, quick="Euler and gymnax only, 100 steps, N=64, one compile")
    parser.add_argument("--solvers", nargs="+", default=None)
    parser.add_argument("--repeats", type=int, default=None)
    args = parser.parse_args(argv)
    solvers = args.solvers or (["euler"] if args.quick else ["euler", "rk4", "tsit5"])
    repeats = args.repeats or (1 if args.quick else 3)
    num_steps, num_envs = (100, 64) if args.quick else (NUM_STEPS, NUM_ENVS)
    out = output_folder(args)

    programs = {}
    for solver in solvers:
        programs[(f"lerax_like {solver}", "rollout")] = rollout_program(solver, num_steps)
        programs[(f"lerax_like {solver}", "step")] = step_program(
            lambda solver=solver: lerax_program(solver), num_steps, num_envs
        )
    programs[("gymnax", "step")] = step_program(gymnax_program, num_steps, num_envs)

    print(f"{num_steps}-step scanned programs (step: N={num_envs}), min of {repeats} fresh compiles, "
          f"load average {os.getloadavg()}")
    results = {name: [] for name in programs}
    for _ in range(repeats):
        for name, (make, inputs) in programs.items():
            results[name].append(measure(make, inputs))
    rows = []
    for (implementation, kind), measurements in results.items():
        best = {field: min(m[field] for m in measurements) for field in measurements[0]}
        rows.append({"implementation": implementation, "program": kind, **best})
        print(f"{implementation:18s} {kind:8s} lower {best['lower_wall_s']:6.2f} s  compile {best['compile_wall_s']:6.2f} s  "
              f"total {best['total_wall_s']:6.2f} s wall, {best['total_cpu_s']:6.2f} s CPU")
    write_csv(rows, out / "compile_time.csv", cell=lambda v: f"{v:.4f}" if isinstance(v, float) else v)


if __name__ == "__main__":
    main()
