"""Latency of one Gymnasium-layer step against the JAX floor and against Gymnasium, in one run.

Single env, one `step(action)` call at a time, random actions, reset (untimed) when an
episode ends:
- `lerax_like/CartPole-v1` through `gymnasium.make` (with Gymnasium's wrappers) and its
  `unwrapped` env;
- the layer's compiled step alone (`unwrapped.split.compiled.step` + `np.asarray`), to split
  the layer's Python bookkeeping from the jitted call;
- the JAX floor: one bare `jax.jit` function that takes the same arrays as the layer's
  compiled step (packed parameters; action, step count and float64 state packed in one
  array; a key for a stochastic scene) and returns arrays of the same shapes and dtypes (from
  `jax.eval_shape` of the compiled step) without computing anything, fetched with
  `np.asarray` (what any layer must at least do per step);
- Gymnasium's numpy `CartPole-v1` through `gymnasium.make` and unwrapped.
Vector envs at N (default 1024): `make_vec("lerax_like/CartPole-v1", vectorization_mode=
"vector_entry_point")` against Gymnasium's numpy vector CartPole, steps per second, and the
vector step's JAX floor (a bare jitted call with its inputs and outputs, plus `np.asarray`).

Each candidate is timed per call; a block's statistic is the median call, and the
blocks of all candidates are interleaved; the minimum over blocks is reported.

    python -m benchmarks latency [--quick]
    python -m benchmarks.latency [--steps 1000] [--repeats 7] [--vector-envs 1024] [--out DIR]

Writes latency.csv into benchmarks/results/ (results/quick/ with --quick).
"""

import argparse
import os
import pathlib
import statistics
import time

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np

import lerax_like  # noqa: F401  (registers the lerax_like/ ids)
from benchmarks import results_dir, write_csv
from lerax_like.gym._compiled import float64, pack_step


def gym_stepper(env, actions):
    """A thunk that times `len(actions)` single steps of `env`; returns their median in seconds."""
    env.reset(seed=0)

    def block():
        times = []
        for action in actions:
            start = time.perf_counter()
            _, _, terminated, truncated, _ = env.step(action)
            times.append(time.perf_counter() - start)
            if terminated or truncated:
                env.reset()
        return statistics.median(times)

    return block


def _fetch(outputs):
    # What the layer does with its results: `np.asarray` per array (`jax.device_get`
    # costs far more for arrays this small).
    return [np.asarray(output) for output in outputs]


def _bare(shapes):
    """A jitted function of any arguments returning zeros of `shapes` (a `jax.eval_shape` result)."""

    @jax.jit
    def bare(*arguments):
        del arguments
        return jax.tree.map(lambda shape: jnp.zeros(shape.shape, shape.dtype), shapes)

    return bare


def call_stepper(env, actions, *, floor: bool):
    """The layer's jitted step alone, as `GymnasiumEnv.step` calls it, without its
    bookkeeping; with `floor`, the JAX floor: a bare jitted call with the same inputs and
    outputs that computes nothing."""
    split = env.unwrapped.split
    env.reset(seed=0)
    y = np.array(env.unwrapped.state)
    key = split.key(0)
    call = split.compiled.step
    packed = [pack_step(y, 0, action) for action in actions]
    if floor:
        with float64():
            call = _bare(jax.eval_shape(split.compiled.step, split.parameters, packed[0], key))
            jax.block_until_ready(call(split.parameters, packed[0], key))

    def block():
        nonlocal key
        times = []
        with float64():
            for action, inputs in zip(actions, packed, strict=True):
                start = time.perf_counter()
                if not floor:  # the layer packs its inputs; the floor does not
                    inputs = pack_step(y, 0, action)
                *outputs, key = call(split.parameters, inputs, key)
                _fetch(outputs)
                times.append(time.perf_counter() - start)
        return statistics.median(times)

    return block


def vector_stepper(env, num_steps):
    """Seconds for `num_steps` vector steps with random actions (next-step autoreset)."""
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    num_envs = env.num_envs

    def block():
        start = time.perf_counter()
        for _ in range(num_steps):
            env.step(rng.integers(0, 2, num_envs))
        return time.perf_counter() - start

    return block


def vector_call_stepper(env, num_steps, *, floor: bool):
    """Seconds for `num_steps` calls of the batch's jitted vector step (no restarts:
    `batch_advance`) plus `np.asarray` of its results, without the layer's bookkeeping;
    with `floor`, of a bare jitted call with the same inputs and outputs that computes
    nothing (the JAX floor)."""
    batch = env.unwrapped.batch
    env.reset(seed=0)
    parameters, key, observation = batch.parameters, batch.key, batch.observation
    with float64():
        y, steps = jnp.asarray(batch.state), jnp.asarray(batch.steps)
    rng = np.random.default_rng(0)
    num_envs = env.num_envs
    call = batch.compiled.batch_advance
    if floor:
        with float64():
            arguments = (parameters, y, steps, np.zeros(num_envs, dtype=np.int64), key, observation)
            call = _bare(jax.eval_shape(batch.compiled.batch_advance, *arguments))
            jax.block_until_ready(call(*arguments))

    def block():
        start = time.perf_counter()
        with float64():
            for _ in range(num_steps):
                actions = rng.integers(0, 2, num_envs)
                _, _, *outputs, _ = call(parameters, y, steps, actions, key, observation)
                _fetch(outputs)
        return time.perf_counter() - start

    return block


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer steps and repeats")
    parser.add_argument("--steps", type=int, default=None, help="single-env steps per block")
    parser.add_argument("--repeats", type=int, default=None)
    parser.add_argument("--vector-envs", type=int, default=None, help="1024 (64 with --quick)")
    parser.add_argument("--vector-steps", type=int, default=None)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    num_steps = args.steps or (200 if args.quick else 1000)
    repeats = args.repeats or (2 if args.quick else 7)
    vector_steps = args.vector_steps or (20 if args.quick else 200)
    actions = np.random.default_rng(1).integers(0, 2, num_steps)

    ours = gymnasium.make("lerax_like/CartPole-v1")
    theirs = gymnasium.make("CartPole-v1")
    single = {
        "lerax_like gym.make step": gym_stepper(ours, actions),
        "lerax_like unwrapped step": gym_stepper(ours.unwrapped, actions),
        "lerax_like compiled step + fetch": call_stepper(ours, actions, floor=False),
        "JAX floor: bare jitted call + fetch": call_stepper(ours, actions, floor=True),
        "Gymnasium CartPole gym.make step": gym_stepper(theirs, actions),
        "Gymnasium CartPole unwrapped step": gym_stepper(theirs.unwrapped, actions),
    }
    n = args.vector_envs or (64 if args.quick else 1024)
    our_vector = gymnasium.make_vec("lerax_like/CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
    vector = {
        f"lerax_like vector env, N={n}": vector_stepper(our_vector, vector_steps),
        f"lerax_like compiled vector step + fetch, N={n}": vector_call_stepper(our_vector, vector_steps, floor=False),
        f"JAX floor of a vector step, N={n}": vector_call_stepper(our_vector, vector_steps, floor=True),
        f"Gymnasium vector CartPole, N={n}": vector_stepper(
            gymnasium.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point"), vector_steps
        ),
    }
    for block in vector.values():
        block()  # compiles and warms up

    print(f"jax {jax.__version__}, gymnasium {gymnasium.__version__}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()}; {num_steps} steps a block, {repeats} interleaved blocks")
    results = {name: [] for name in {**single, **vector}}
    for _ in range(repeats):
        for name, block in {**single, **vector}.items():
            results[name].append(block())

    floor = min(results["JAX floor: bare jitted call + fetch"])
    gymnasium_step = min(results["Gymnasium CartPole gym.make step"])
    rows = []
    for name in single:
        seconds = min(results[name])
        rows.append({"measurement": name, "seconds_per_step": seconds, "vs_jax_floor": seconds / floor,
                     "vs_gymnasium_make_step": seconds / gymnasium_step, "steps_per_s": 1 / seconds})
        print(f"{name:42s} {seconds * 1e6:8.1f} us/step  x{seconds / floor:5.2f} floor  "
              f"x{seconds / gymnasium_step:6.2f} Gymnasium")
    theirs_vector = min(results[f"Gymnasium vector CartPole, N={n}"])
    for name in vector:
        seconds = min(results[name]) / vector_steps
        rows.append({"measurement": name, "seconds_per_step": seconds, "vs_jax_floor": float("nan"),
                     "vs_gymnasium_make_step": float("nan"), "steps_per_s": n / seconds})
        print(f"{name:42s} {seconds * 1e6:8.1f} us/vector step  {n / seconds / 1e6:7.2f} M steps/s  "
              f"x{theirs_vector / min(results[name]):5.2f} Gymnasium vector speed")
    print(f"load average at the end {os.getloadavg()}")
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "latency.csv", rows)


if __name__ == "__main__":
    main()
