"""Adaptive solvers under `vmap` cost as much as the slowest batch element: measured, with remedies.

`diffeqsolve` with an adaptive controller runs a `while_loop`; under `jax.vmap` the loop
runs until the last element is done, every element computing every iteration (the
finished ones discard their result). One hard element in a batch makes the whole batch
pay for it. Workload: the throughput workload (`_workload.py`) with N CartPoles whose
pole half lengths differ, `solver="tsit5"` (PIDController rtol=1e-6, atol=1e-9); an
"easy" pole has the default half length 0.5 m, a "hard" one 0.005 m (fast dynamics, about
four Tsit5 steps per env step instead of one).

Rows (one run, repeats interleaved):
- all easy / one hard among N / all hard: the cost of the batch;
- grouped: the same N envs as one batch of the N-1 easy ones plus one batch of the hard one
  (remedy: group envs by parameters, or use smaller batches);
- RK4 fixed step, one hard among N: the same mixed batch with a fixed-step solver
  (remedy: a fixed step where accuracy allows), whose cost does not depend on the mix.

    python -m benchmarks adaptive_vmap             # N=1024, T=200
    python -m benchmarks adaptive_vmap --quick     # N=64, T=20, 2 repeats
    python -m benchmarks.adaptive_vmap --envs 256 --steps 100 --out DIR

Writes adaptive_vmap.csv into benchmarks/results/ (results/quick/ with --quick).
"""

import os

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

import lerax_like
from benchmarks import output_folder, sized_arguments
from benchmarks._workload import interleaved, summary
from lerax_like.analysis.recording import write_csv


EASY, HARD = 0.5, 0.005


def make_envs(half_lengths, solver):
    return eqx.filter_vmap(lambda length: lerax_like.make("CartPole", half_length=length, solver=solver))(half_lengths)


def episode(env, key, num_steps):
    """The workload of one env; returns the total reward, final state and solver steps per env step."""
    reset_key, key = jr.split(key)
    state, _, _ = env.reset(key=reset_key)

    def body(carry, _):
        state, key, total = carry
        key, action_key, step_key = jr.split(key, 3)
        action = jr.randint(action_key, (), 0, 2)
        state, _, reward, _, _, info = env.step(state, action, key=step_key)
        return (state, key, total + reward), info["solver_steps"]

    (state, _, total), solver_steps = jax.lax.scan(body, (state, key, jnp.zeros(())), None, length=num_steps)
    return total, state, solver_steps


def program(envs, num_steps):
    @eqx.filter_jit
    def run(envs, keys):
        return eqx.filter_vmap(lambda env, key: episode(env, key, num_steps))(envs, keys)

    return run


def main(argv=None):
    args = sized_arguments(__doc__, argv, quick=(64, 20, 2), full=(1024, 200, 5))
    out = output_folder(args)
    n = args.envs
    keys = jr.split(jr.key(0), n)

    easy = jnp.full((n,), EASY)
    one_hard = easy.at[0].set(HARD)
    batches = {
        "Tsit5, all easy": (make_envs(easy, "tsit5"), keys),
        "Tsit5, one hard among N": (make_envs(one_hard, "tsit5"), keys),
        "Tsit5, all hard": (make_envs(jnp.full((n,), HARD), "tsit5"), keys),
        "Tsit5, grouped: N-1 easy": (make_envs(easy[1:], "tsit5"), keys[1:]),
        "Tsit5, grouped: 1 hard": (make_envs(one_hard[:1], "tsit5"), keys[:1]),
        "RK4 fixed step, all easy": (make_envs(easy, "rk4"), keys),
        "RK4 fixed step, one hard among N": (make_envs(one_hard, "rk4"), keys),
    }
    thunks, work = {}, {}
    for name, (envs, batch_keys) in batches.items():
        run = program(envs, args.steps)
        _, _, solver_steps = jax.block_until_ready(run(envs, batch_keys))  # compiles
        # solver_steps: (batch, T). The loop runs max-over-batch iterations at each env step.
        work[name] = (float(jnp.mean(solver_steps)), float(jnp.mean(jnp.max(solver_steps, axis=0))))
        thunks[name] = lambda run=run, envs=envs, batch_keys=batch_keys: jax.block_until_ready(run(envs, batch_keys))

    print(f"N={n}, T={args.steps}, {args.repeats} interleaved repeats, load average {os.getloadavg()}")
    times = interleaved(thunks, args.repeats)
    best = {name: summary(seconds)[0] for name, seconds in times.items()}
    best["Tsit5, grouped (both batches)"] = best["Tsit5, grouped: N-1 easy"] + best["Tsit5, grouped: 1 hard"]
    work["Tsit5, grouped (both batches)"] = (float("nan"), float("nan"))
    reference = best["Tsit5, all easy"]
    rows = []
    for name, seconds in best.items():
        mean_steps, paid_steps = work[name]
        rows.append({"batch": name, "min_s": f"{seconds:.5f}", "time_vs_all_easy": f"{seconds / reference:.3f}",
                     "mean_solver_steps": f"{mean_steps:.3f}", "max_over_batch_solver_steps": f"{paid_steps:.3f}"})
        print(f"{name:36s} {seconds * 1e3:9.1f} ms  x{seconds / reference:6.2f} all-easy  "
              f"solver steps per env step: mean {mean_steps:5.2f}, loop iterations {paid_steps:5.2f}")
    write_csv(rows, out / "adaptive_vmap.csv")


if __name__ == "__main__":
    main()
