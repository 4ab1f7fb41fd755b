"""Benchmarks that compare lerax_like with its peers in one run, and the runner that records them.

    python -m benchmarks NAME|all [--quick]     # run, write CSVs under results/, regenerate RESULTS.md
    python -m benchmarks list                   # the benchmarks, their peers, whether each is installed
    python -m benchmarks report                 # regenerate RESULTS.md from the recorded files only

Each benchmark is a module `benchmarks.NAME` with `main(argv)`; `python -m benchmarks.NAME
[options]` runs one with its own options (`--help`), which the runner passes on after `--`
(`python -m benchmarks throughput -- --envs 1024 16384 --repeats 7`).

Recorded results live in `benchmarks/results/`; each run also writes `NAME.run.json` there
(the command, date, machine, load, library versions and a hash of every file it wrote), from
which `benchmarks/RESULTS.md` is generated. `--quick` runs write to `benchmarks/results/quick/`
(git-ignored, with its own RESULTS.md), so a smoke run never touches the recorded results.
"""

import argparse
import csv
import dataclasses
import pathlib


HERE = pathlib.Path(__file__).resolve().parent
RESULTS = HERE / "results"
QUICK_RESULTS = RESULTS / "quick"


def results_dir(quick: bool) -> pathlib.Path:
    """Where a benchmark writes by default: the recorded results, or the git-ignored quick folder."""
    return QUICK_RESULTS if quick else RESULTS


def benchmark_parser(description: str, quick: str) -> argparse.ArgumentParser:
    """A benchmark's command line with the two options the runner passes: `--quick` (`quick`
    says what it shrinks) and `--out` (the folder, default `results_dir`); add its own."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help=quick)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    return parser


def sized_arguments(
    description: str, argv, *, quick: tuple[int, int, int], full: tuple[int, int, int]
) -> argparse.Namespace:
    """The command line of a benchmark sized by `--envs N`, `--steps T` and `--repeats R`:
    each defaults to `full`'s `(N, T, R)`, or to `quick`'s with `--quick`."""
    parser = benchmark_parser(description, quick="N={}, T={}, {} repeats".format(*quick))
    for name in ("envs", "steps", "repeats"):
        parser.add_argument(f"--{name}", type=int, default=None)
    arguments = parser.parse_args(argv)
    for name, small, large in zip(("envs", "steps", "repeats"), quick, full):
        if getattr(arguments, name) is None:
            setattr(arguments, name, small if arguments.quick else large)
    return arguments


def write_csv(path: pathlib.Path, rows: list[dict]) -> None:
    """`rows` (dicts with the same keys) as a CSV file, floats to 6 significant figures."""
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})


def output_folder(arguments: argparse.Namespace) -> pathlib.Path:
    """Where a benchmark parsed by `benchmark_parser` writes: `--out` or `results_dir`, created."""
    out = pathlib.Path(arguments.out or results_dir(arguments.quick))
    out.mkdir(parents=True, exist_ok=True)
    return out


@dataclasses.dataclass(frozen=True)
class Benchmark:
    name: str
    summary: str
    # Modules that must be importable, with the install hint shown when one is missing.
    needs: tuple[tuple[str, str], ...] = ()
    # Extra environment for the benchmark's process (sharding needs several host devices).
    environment: tuple[tuple[str, str], ...] = ()


_STUDY = ("scipy", "pip install -e '.[study]'")
_PLOTS = ("matplotlib", "pip install -e '.[study]'")
_GYMNAX = ("gymnax", "pip install -e '.[bench]'")
_OPTAX = ("optax", "pip install -e '.[test]'")
_SB3 = ("stable_baselines3", "pip install stable-baselines3 (with a CPU torch)")
_REJAX = ("rejax", "pip install -e '.[bench]'")

# In the order `all` runs them.
BENCHMARKS = {
    benchmark.name: benchmark
    for benchmark in (
        Benchmark("work_precision", "error against run time of every solver, per scene (the main job)", (_STUDY, _PLOTS)),
        Benchmark("gradient_error", "gradient error against run time, per solver and step", (_STUDY, _PLOTS)),
        Benchmark("gradient_variance", "first- against zeroth-order gradient estimators against the horizon", (_STUDY, _PLOTS)),
        Benchmark("gradient_precision", "float32 against float64 gradients: the horizon where float32 loses the leading digit, per scene"),
        Benchmark("gradient_memory", "memory and time of a 1000-step rollout's gradient: storing against checkpointing"),
        Benchmark(
            "gradient_cost", "a batched rollout's gradient (reverse and forward mode) against a hand-written JAX floor",
            (_GYMNAX,),
        ),
        Benchmark("throughput", "env steps per second against the number of envs, beside gymnax and Gymnasium", (_GYMNAX, _PLOTS)),
        Benchmark("profile_step", "where the time of a vmapped env step goes, part by part, beside gymnax", (_GYMNAX,)),
        Benchmark("compile_time", "compile time of 1000-step scanned programs, beside gymnax", (_GYMNAX,)),
        Benchmark("contact_compile", "compile time of gradient programs through located walls and friction, beside the same cart-pole without them"),
        Benchmark("adaptive_vmap", "adaptive solvers under vmap: one hard env in a batch, and the remedies"),
        Benchmark("latency", "one Gymnasium-layer step against the JAX floor and Gymnasium's own step"),
        Benchmark("gym_vector", "the Gymnasium-layer vector env of every id against the XLA floor and Gymnasium's vector envs"),
        Benchmark("contact_study", "work-precision through contact: located walls' fitted orders beside penalty end stops'", (_STUDY, _PLOTS)),
        Benchmark("rimless_wheel", "the passive rimless wheel's limit cycle from the env's located impacts, to 1e-9", (_STUDY,)),
        Benchmark("walkers", "the simplest walker's and the compass gait's gaits against slope, eigenvalues, period doubling", (_STUDY,)),
        Benchmark("stability", "stiff and extreme cases: status and error per solver, and Kvaerno5's root finders", (_STUDY,)),
        Benchmark("domain_randomisation", "a policy trained over pole masses against one trained at the nominal mass", (_OPTAX, _STUDY)),
        Benchmark("ppo_baseline", "PPO (Stable-Baselines3) on the policy-learning task", (_SB3,)),
        Benchmark("jax_rl", "rejax's PPO on gymnax's CartPole and on lerax_like.gymnax's (euler, rk4, tsit5): time and return", (_GYMNAX, _REJAX)),
        Benchmark("sb3_vector", "PPO on lerax_like.sb3.make_vec_env against SB3's make_vec_env; the VecEnvs' speed", (_SB3,)),
        Benchmark(
            "cleanrl_loop", "a CleanRL-shaped SyncVectorEnv loop: import, compile and step, with JAX's persistent cache",
        ),
        Benchmark("contact", "located walls against penalty end stops: throughput and accuracy against SciPy", (_STUDY, _PLOTS)),
        Benchmark("friction", "located stick-slip against tanh-regularised friction at matched stop distance: forward and gradient cost"),
        Benchmark(
            "frictional_contact",
            "a disk launched sliding: located frictional contact against tanh friction and a penalty floor",
        ),
        Benchmark(
            "friction_bias", "the pathwise gradient's bias through friction: located stick-slip against tanh at three sharpnesses",
            (_PLOTS,),
        ),
        Benchmark(
            "contact_gradient_variance", "first-order gradient bias and variance through located walls and penalty end stops",
            (_STUDY, _PLOTS),
        ),
        Benchmark(
            "gym_before_after", "the vector env's and the SB3 VecEnv's speed against an older commit's, interleaved",
            (_SB3,),
        ),
        Benchmark("render", "time per frame of every scene's NumPy picture, beside Gymnasium's pygame pictures"),
        Benchmark(
            "sharded_rollout", "rollouts sharded over devices equal the unsharded run",
            environment=(("XLA_FLAGS", "--xla_force_host_platform_device_count=4"),),
        ),
    )
}
