"""Where the time of a vmapped `CartPole.step` goes: per-part timings in one run.

Each variant runs the shared workload (`_workload.py`: N envs, random actions, T steps in
one scan) and adds one part of `AbstractEnv.step` at a time, so the differences between
rows are the costs of the parts. gymnax's CartPole runs beside them as the reference.

    python -m benchmarks profile_step            # N=1024, T=500, 7 interleaved repeats
    python -m benchmarks profile_step --quick    # N=64, T=100, 2 repeats
    python -m benchmarks.profile_step --envs 64 --repeats 3 --out DIR

Writes profile_step.csv into benchmarks/results/ (results/quick/ with --quick).
"""

import os

import jax
import jax.numpy as jnp
import jax.random as jr

import lerax_like
from benchmarks import output_folder, sized_arguments
from benchmarks._workload import batched, compile_seconds, gymnax_program, interleaved, scanned, summary
from lerax_like.analysis.recording import write_csv
from lerax_like.env import EnvState


def hand_euler(env, y, u):
    # The Euler line that gymnax and Gymnasium write by hand.
    return y + env.dt * env.dynamics.vector_field(0.0, y, u)


def variants(env):
    """name -> (step, initial), from the bare physics up to the full `env.step`."""

    def initial(key):
        return env.reset(key=key)[0]

    def physics_only(state, action, key):
        del key
        y = hand_euler(env, state.y, env.physical_input(action))
        return EnvState(y=y, steps=state.steps + 1), jnp.ones(())

    def diffeqsolve_only(state, action, key):
        del key
        y, _ = env.integrator.integrate(env.dynamics.vector_field, state.y, env.physical_input(action), env.dt)
        return EnvState(y=y, steps=state.steps + 1), jnp.ones(())

    def hand_step(start):
        """Hand-written Euler, termination, truncation and the restart from `start(key)`,
        drawn every step (under `vmap` a `cond` on `done` is a `select` of both branches)."""

        def step(state, action, key):
            y = hand_euler(env, state.y, env.physical_input(action))
            next_state = EnvState(y=y, steps=state.steps + 1)
            done = env.terminal(next_state, key=None) | env.truncate(next_state)
            new_state = jax.tree.map(lambda a, b: jnp.where(done, a, b), start(key), next_state)
            return new_state, jnp.ones(())

        return step

    def constant_start(key):
        # No key work at all: `step` without the reset sampling and without key splitting.
        del key
        return EnvState(y=jnp.zeros(4, dtype=env.dt.dtype), steps=jnp.zeros((), dtype=int))

    def gymnax_start(key):
        # gymnax's key work: one split in two, then the reset's own draw.
        return env.initial(key=jr.split(key)[1])

    def first_version_start(key):
        # The key work of `AbstractEnv.step`'s first version: split in five, then `reset`
        # split in two again.
        return env.initial(key=jr.split(jr.split(key, 5)[4])[0])

    def one_hash_start(key):
        # As `AbstractEnv.step` now draws it for a deterministic scene: the step's key goes
        # to `initial`, which spends one hash on four 16-bit coordinates.
        return env.initial(key=key)

    def full_step(state, action, key):
        state, _, reward, _, _, _ = env.step(state, action, key=key)
        return state, reward

    return {
        "physics only (hand Euler)": (physics_only, initial),
        "physics only (Integrator Euler)": (diffeqsolve_only, initial),
        "hand step, constant reset": (hand_step(constant_start), initial),
        "hand step, gymnax key work": (hand_step(gymnax_start), initial),
        "hand step, split(5)+split(2) keys": (hand_step(first_version_start), initial),
        "hand step, one-hash start": (hand_step(one_hash_start), initial),
        "env.step (Euler)": (full_step, initial),
    }


def main(argv=None):
    args = sized_arguments(__doc__, argv, quick=(64, 100, 2), full=(1024, 500, 7))
    out = output_folder(args)

    env = lerax_like.make("CartPole", solver="euler")
    runs = {}
    for name, (step, initial) in {**variants(env), "gymnax CartPole-v1": gymnax_program()}.items():
        run = batched(scanned(step, initial, args.steps), args.envs)
        key = jr.key(0)
        _, compiled = compile_seconds(run, key)
        jax.block_until_ready(compiled(key))
        runs[name] = (lambda compiled=compiled, key=key: jax.block_until_ready(compiled(key)))

    times = interleaved(runs, args.repeats)
    reference = summary(times["gymnax CartPole-v1"])[0]
    rows = []
    print(f"N={args.envs}, T={args.steps}, {args.repeats} interleaved repeats, load average {os.getloadavg()}; "
          "time relative to gymnax (min)")
    for name, seconds in times.items():
        best, median = summary(seconds)
        steps_per_second = args.envs * args.steps / best
        rows.append({"variant": name, "min_s": f"{best:.5f}", "median_s": f"{median:.5f}",
                     "steps_per_s": f"{steps_per_second:.4g}", "time_vs_gymnax": f"{best / reference:.3f}"})
        print(f"{name:36s} min {best * 1e3:8.2f} ms  median {median * 1e3:8.2f} ms  "
              f"{steps_per_second / 1e6:7.2f} M steps/s  x{best / reference:5.2f} gymnax time")
    write_csv(rows, out / "profile_step.csv")


if __name__ == "__main__":
    main()
