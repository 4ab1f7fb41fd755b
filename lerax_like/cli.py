"""The `lerax-like` command: argument parsing only; the work is in `lerax_like.analysis`.

    lerax-like study CartPole [--quick] [--out DIR] [--solver NAME ...] [--substeps N ...]
    lerax-like study mymodule:MyScene --quick        (a scene class from the working directory)
    lerax-like gradients CartPole [--quick] [--out DIR] [--no-plot] [--solver NAME ...] [--scene-keyword KEY=NUMBER ...]
    lerax-like gradient-variance DoubleCartPole [--quick] [--solver NAME ...] [--out DIR] [--no-plot] [--scene-keyword KEY=NUMBER ...]
    lerax-like rollout CartPole [--steps N] [--seed S]
    lerax-like solvers
    lerax-like gait SimplestWalker [--scene-keyword slope=0.01] [--no-sensitivity]
"""

import argparse
import dataclasses
import os
import sys
import time


SOLVER_HELP = (
    "a solver to study, repeatable: a preset (see `lerax-like solvers`) or 'module:attribute' naming a "
    "diffrax solver instance or a solver class built with no arguments ('diffrax:Bosh3', "
    "'my_methods:RALSTON3'; the module is imported from the current directory or PYTHONPATH). Solvers "
    "without an error estimate are swept over substeps, those with one over substeps and tolerances. "
    "Default: the study's own set"
)


SCENE_HELP = (
    "a registered scene ({scenes}), or 'module:Class' naming a scene class (a final AbstractEnv subclass) "
    "in a module of the current directory or PYTHONPATH, which is registered under its class name"
)


def scene_from_spec(spec: str) -> str:
    """The registered name of the scene a command line names: a name, or `module:Class`.

    `module:Class` imports `module` as `solver_from_spec` does and registers `Class` (a
    final `AbstractEnv` subclass) with `register_scene`, unless it registered itself.
    Raises `ValueError` naming what is wrong.
    """
    from .env import AbstractEnv
    from .integrate._spec import attribute_from_spec
    from .scenes import SCENES, register_scene

    if ":" not in spec:
        if spec not in SCENES:
            raise ValueError(f"unknown scene {spec!r}: {SCENE_HELP.format(scenes=', '.join(sorted(SCENES)))}")
        return spec
    value = attribute_from_spec(spec, "scene")
    if not (isinstance(value, type) and issubclass(value, AbstractEnv)):
        raise ValueError(f"scene {spec!r}: {value!r} is not a scene class (a subclass of lerax_like.AbstractEnv)")
    try:
        register_scene(value)
    except (TypeError, ValueError) as error:
        raise ValueError(f"scene {spec!r}: {error}") from None
    return value.__name__


def _working_directory_importable() -> None:
    # `python -m lerax_like` puts the working directory on sys.path, but the `lerax-like`
    # console script puts its own folder there instead: without this, `--solver
    # mymethods:RALSTON3` (or the scene `mymodule:MyScene`) run beside mymethods.py would
    # not find it.
    if os.getcwd() not in sys.path and "" not in sys.path:
        sys.path.insert(0, os.getcwd())


def _solvers_from(arguments, command: str):
    """The solvers named by `--solver`, or None; a bad name is a usage error (exit 2)."""
    if not arguments.solver:
        return None
    _working_directory_importable()
    try:
        from .integrate import solver_from_spec

        return [solver_from_spec(spec) for spec in arguments.solver]
    except ValueError as error:
        print(f"lerax-like {command}: {error}", file=sys.stderr)
        sys.exit(2)


def _scene_from(arguments, command: str) -> str:
    """The registered name of the scene argument (`module:Class` imported and registered); exit 2 if bad."""
    _working_directory_importable()
    try:
        return scene_from_spec(arguments.scene)
    except ValueError as error:
        print(f"lerax-like {command}: {error}", file=sys.stderr)
        sys.exit(2)


def _scene_keywords(arguments, command: str) -> dict[str, float]:
    """The scene's keywords named by `--scene-keyword KEY=NUMBER`; a malformed one is a usage error (exit 2)."""
    try:
        return {key: float(value) for key, value in (pair.split("=", 1) for pair in arguments.scene_keyword)}
    except ValueError:
        print(f"lerax-like {command}: --scene-keyword takes KEY=NUMBER, got {arguments.scene_keyword}", file=sys.stderr)
        sys.exit(2)


def _given(arguments, *names: str) -> dict:
    """The options of `names` that the command line gives (those not None), by name."""
    return {name: getattr(arguments, name) for name in names if getattr(arguments, name) is not None}


def _study(arguments) -> int:
    from .analysis.recording import matplotlib_available
    from .analysis.study import VERDICT_TARGETS, StudyConfig, run_study, sweeps_for
    from .analysis.sweeps import with_substeps
    from .analysis.tables import format_orders, format_table
    from .analysis.verdict import cheapest_at, order_disagreements, verdict_line
    from .analysis.scenes import SCENES

    arguments.scene = _scene_from(arguments, "study")
    overrides = _given(arguments, "seed", "horizon")
    solvers = _solvers_from(arguments, "study")
    if solvers is not None:
        overrides["sweeps"] = sweeps_for(solvers, quick=arguments.quick, stiff=SCENES[arguments.scene].stiff)
    if arguments.scene_keyword:
        overrides["scene_kwargs"] = _scene_keywords(arguments, "study")
    config = StudyConfig.default(arguments.scene, quick=arguments.quick, **overrides)
    if arguments.substeps:
        try:
            config = dataclasses.replace(config, sweeps=with_substeps(config.sweeps, arguments.substeps))
        except ValueError as error:
            print(f"lerax-like study: --substeps: {error}", file=sys.stderr)
            return 2
    plot = not arguments.no_plot and matplotlib_available()
    start = time.perf_counter()
    result = run_study(config, progress=not arguments.no_progress)
    elapsed = time.perf_counter() - start
    paths = result.write(arguments.out, plot=plot, study_seconds=elapsed)
    print(format_table(result.rows))
    print()
    print("Convergence orders (fixed steps; errors between the reference floor and "
          f"{config.fit_ceiling:g}):")
    print(format_orders(result.convergence_orders()))
    print()
    for target in VERDICT_TARGETS:
        verdict = verdict_line(cheapest_at(result.rows, target))
        print(f"cheapest at error <= {target:g} ({config.schedules[0]} actions): {verdict}")
    for line in order_disagreements(result.convergence_orders()):
        print(f"order disagrees: {line}")
    return _finish(arguments, plot, elapsed, paths)


def _finish(arguments, plot: bool, elapsed: float, paths: dict[str, str]) -> int:
    """The closing lines of a study: the plot skipped (and why), the time, the files."""
    from .analysis.recording import PLOT_HINT

    print()
    if not arguments.no_plot and not plot:
        print(f"plot skipped: matplotlib is not installed ({PLOT_HINT})")
    print(f"study took {elapsed:.1f} s; wrote " + ", ".join(paths.values()))
    return 0


def _gradients(arguments) -> int:
    from .analysis.gradient_accuracy import GradientStudyConfig, run_gradient_study
    from .analysis.tables import format_gradient_table

    arguments.scene = _scene_from(arguments, "gradients")
    overrides = {"mode": arguments.mode, **_given(arguments, "seed", "horizon")}
    if arguments.scene_keyword:
        overrides["scene_kwargs"] = _scene_keywords(arguments, "gradients")
    solvers = _solvers_from(arguments, "gradients")
    if solvers is not None:
        from .analysis.gradient_accuracy import gradient_sweeps_for

        overrides["sweeps"] = gradient_sweeps_for(solvers, quick=arguments.quick)
    try:
        config = GradientStudyConfig.default(arguments.scene, quick=arguments.quick, **overrides)
    except ValueError as error:
        print(f"lerax-like gradients: {error}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    result = run_gradient_study(config)
    elapsed = time.perf_counter() - start
    from .analysis.recording import matplotlib_available

    plot = not arguments.no_plot and matplotlib_available()
    paths = result.write(arguments.out, plot=plot, study_seconds=elapsed)
    reference = result.record["reference"]
    print(f"{config.scene}: gradient of {config.cost.__name__} over {config.horizon} env steps with respect to "
          f"{', '.join(result.record['parameter_names'])} ({config.mode} mode); error relative to "
          f"{'SciPy through the switches' if 'dopri8_discrepancy' in reference else 'Dopri8'} at "
          f"rtol {reference['rtol']:g} (its floor {reference['floor']:.1e})")
    print(format_gradient_table(result.rows))
    print()
    print(f"Orders of the gradient error (fixed steps; errors between the floor and {config.fit_ceiling:g}):")
    for entry in result.convergence_orders():
        if entry["order"] is None:
            print(f"{entry['solver']:<9} order {entry['note']}")
        else:
            print(f"{entry['solver']:<9} order {entry['order']:.2f} ({entry['points']} points)")
    return _finish(arguments, plot, elapsed, paths)


def _gradient_variance(arguments) -> int:
    from .analysis.gradient_variance import (
        GradientVarianceConfig,
        run_gradient_variance,
        summary,
        write_gradient_variance,
    )
    from .analysis.recording import matplotlib_available
    from .analysis.tables import format_gradient_variance_table

    arguments.scene = _scene_from(arguments, "gradient-variance")
    overrides = _given(arguments, "seed", "dtype")
    if arguments.solver:
        overrides["solvers"] = tuple(arguments.solver)
    keywords = _scene_keywords(arguments, "gradient-variance") if arguments.scene_keyword else {}
    cases = [{"end_stop_stiffness": k} for k in arguments.end_stop_stiffness or []]
    cases += [{"restitution": e} for e in arguments.restitution or []]
    try:
        configs = [
            GradientVarianceConfig.default(
                arguments.scene, quick=arguments.quick, scene_kwargs={**keywords, **kwargs}, **overrides
            )
            for kwargs in cases or [{}]
        ]
        start = time.perf_counter()
        results = [run_gradient_variance(config, progress=lambda m: print(m, file=sys.stderr)) for config in configs]
        elapsed = time.perf_counter() - start
    except ValueError as error:
        print(f"lerax-like gradient-variance: {error}", file=sys.stderr)
        return 2
    if arguments.scene == "CartPole":
        print("CartPole is studied through CartPoleContinuous: a force of action * force_mag newtons, "
              "continuous, so that the cost is differentiable in the actions")
    plot = not arguments.no_plot and matplotlib_available()
    paths = write_gradient_variance(results, arguments.out, stem=f"{arguments.scene}_gradient_variance",
                                    plot=plot, study_seconds=elapsed)
    for result in results:
        print()
        print(f"{result.config.name}: {result.config.samples} samples per estimator, reference of "
              f"{result.config.reference_samples} antithetic zeroth-order samples ({result.config.dtype})")
        print(format_gradient_variance_table(result.rows))
        for entry in summary(result):
            print(f"  {entry['solver']} {entry['policy']}: first-order variance x"
                  + ", x".join(f"{g:.3g} (sigma {s})" for s, g in entry["first_order_variance_growth"].items())
                  + f" from H={min(result.config.horizons)} to H={max(result.config.horizons)}")
            for c in entry["crossover"]:
                print(f"    sigma {c['sigma']}: Lyapunov exponent {c['lyapunov_exponent']:.3g}/s, variance growth "
                      f"rate {c['variance_growth_rate']:.3g}/s; first order above zeroth order from H = "
                      f"{c['measured_horizon']} (measured), {c['predicted_horizon']} (predicted); agree: {c['agree']}")
            if "float32_first_digit_lost_horizon" in entry:
                print(f"    float32 loses the leading digit at H = {entry['float32_first_digit_lost_horizon']} "
                      f"(searched up to {entry['float32_horizons_searched']}; relative error there "
                      f"{entry['float32_relative_error_at_longest']:.1e})")
    return _finish(arguments, plot, elapsed, paths)


def _rollout(arguments) -> int:
    from .analysis.rollout_check import format_rollouts, preset_rollouts

    rows = preset_rollouts(arguments.scene, steps=arguments.steps, seed=arguments.seed)
    print(f"{arguments.scene}: one episode of {arguments.steps} seeded random actions, "
          f"final-state error against {rows[0]['reference']}")
    print(format_rollouts(rows))
    return 0


def _gait(arguments) -> int:
    from .analysis.gait import scene_gait

    keywords = _scene_keywords(arguments, "gait") if arguments.scene_keyword else {}
    print(scene_gait(arguments.scene, keywords, sensitivity=not arguments.no_sensitivity))
    return 0


def format_solver_table() -> str:
    """The solver presets with their orders, as `lerax-like solvers` prints them."""
    from .integrate import SOLVERS

    header = ("name", "order", "stages", "f-evals/step", "kind", "error estimate", "default controller", "description")
    lines: list[tuple[str, ...]] = [header]
    for preset in SOLVERS.values():
        lines.append((
            preset.name, str(preset.order), "" if preset.stages is None else str(preset.stages),
            "Newton" if preset.evaluations_per_step is None else str(preset.evaluations_per_step),
            "implicit" if preset.implicit else "explicit", "yes" if preset.error_estimate else "no",
            preset.controller, preset.description,
        ))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)


def _solvers(arguments) -> int:
    del arguments
    print(format_solver_table())
    print()
    print("Any diffrax solver works too: `--solver module:attribute` on `study` and `gradients`, "
          "or lerax_like.register_solver(name, factory, order=...) from Python.")
    return 0


def main(argv: list[str] | None = None) -> int:
    from .analysis.scenes import SCENES
    from .integrate import SOLVERS

    parser = argparse.ArgumentParser(
        prog="lerax-like", description="Solver-accuracy studies on continuous-time control envs."
    )
    commands = parser.add_subparsers(dest="command", required=True)

    study = commands.add_parser(
        "study", help="work-precision study of the solvers on a scene",
        description="Work-precision study of solvers on a scene against a SciPy reference.",
        epilog="solver presets:\n" + format_solver_table(), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    scene_help = SCENE_HELP.format(scenes=", ".join(sorted(SCENES)))
    study.add_argument("scene", metavar="SCENE", help=scene_help)
    study.add_argument("--quick", action="store_true", help="a small study, under a minute on 2 cores")
    study.add_argument("--out", default="lerax_like_study", help="folder for CSV, PNG and JSON (default: %(default)s)")
    study.add_argument("--seed", type=int, default=None, help="seed of initial states and actions (default 0)")
    study.add_argument("--horizon", type=int, default=None, metavar="T",
                       help="env steps per trajectory (default: the study's own)")
    study.add_argument("--no-progress", action="store_true", help="no progress bar")
    study.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    study.add_argument("--solver", action="append", metavar="NAME", help=SOLVER_HELP)
    study.add_argument("--substeps", nargs="+", type=int, metavar="N",
                       help="the sweep of fixed steps: N equal solver steps per env step (step dt / N), for every "
                            "fixed-step solver (default: by order, e.g. 16 64 256 for Euler in --quick)")
    scene_keyword_help = ("a numeric keyword of the scene, repeatable: --scene-keyword restitution=0.8 "
                          "--scene-keyword track_limit=0.1 studies CartPoleContinuous with located walls, "
                          "--scene-keyword end_stop_stiffness=1e4 with penalty end stops")
    study.add_argument("--scene-keyword", action="append", metavar="KEY=NUMBER", help=scene_keyword_help)
    study.set_defaults(run=_study)

    gradients = commands.add_parser(
        "gradients", help="gradient error against a tight reference vs run time, per solver and step"
    )
    gradients.add_argument("scene", metavar="SCENE", help=scene_help + "; one that does not clip or wrap its state")
    gradients.add_argument("--quick", action="store_true", help="a small study, well under a minute on 2 cores")
    gradients.add_argument("--out", default="lerax_like_gradients", help="folder for CSV, PNG and JSON (default: %(default)s)")
    gradients.add_argument("--seed", type=int, default=None, help="seed of the initial state and actions (default 0)")
    gradients.add_argument("--horizon", type=int, default=None, metavar="T",
                           help="env steps per trajectory (default: the study's own)")
    gradients.add_argument("--mode", choices=("forward", "reverse"), default="forward",
                           help="jax.jacfwd or jax.grad (default: %(default)s, the cheaper for a few parameters)")
    gradients.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    gradients.add_argument("--solver", action="append", metavar="NAME", help=SOLVER_HELP)
    gradients.add_argument("--scene-keyword", action="append", metavar="KEY=NUMBER", help=scene_keyword_help)
    gradients.set_defaults(run=_gradients)

    variance = commands.add_parser(
        "gradient-variance",
        help="first- vs zeroth-order gradient estimators against horizon: variance, bias, chaos, float32",
    )
    variance.add_argument("scene", metavar="SCENE",
                          help=scene_help + "; one with continuous actions that does not clip or wrap its state "
                               "(CartPole is studied through CartPoleContinuous)")
    variance.add_argument("--quick", action="store_true",
                          help="horizons 10, 30, 100, 256 samples (default: 10 to 200, 512 samples)")
    variance.add_argument("--solver", nargs="+", metavar="NAME", choices=SOLVERS.names,
                          help="solver presets (default: rk4; tsit5 with end stops)")
    variance.add_argument("--end-stop-stiffness", nargs="+", type=float, metavar="K",
                          help="cart-poles: end stops of these stiffnesses (N/m) at 0.5 m, one study each")
    variance.add_argument("--restitution", nargs="+", type=float, metavar="E",
                          help="cart-poles: walls at 0.5 m located as events, of these restitutions, one study each "
                               "(beside any --end-stop-stiffness)")
    variance.add_argument("--dtype", choices=("float64", "float32"), default=None,
                          help="dtype of the estimators (default float64; float32 vs float64 is measured anyway)")
    variance.add_argument("--out", default="lerax_like_gradient_variance",
                          help="folder for CSV, PNG and JSON (default: %(default)s)")
    variance.add_argument("--scene-keyword", action="append", metavar="KEY=NUMBER", help=scene_keyword_help)
    variance.add_argument("--seed", type=int, default=None, help="seed of the samples (default 0)")
    variance.add_argument("--no-plot", action="store_true", help="skip the PNG (no matplotlib needed)")
    variance.set_defaults(run=_gradient_variance)

    rollout = commands.add_parser("rollout", help="one episode with each solver preset, error and wall time")
    rollout.add_argument("scene", choices=sorted(SCENES))
    rollout.add_argument("--steps", type=int, default=200)
    rollout.add_argument("--seed", type=int, default=0)
    rollout.set_defaults(run=_rollout)

    from .analysis.gait import walker_scenes

    gait = commands.add_parser(
        "gait", help="a walker's period-one gait: fixed point, step period, eigenvalues, their derivatives"
    )
    gait.add_argument("scene", choices=walker_scenes())
    gait.add_argument("--scene-keyword", action="append", metavar="KEY=NUMBER",
                      help="a numeric keyword of the scene, repeatable: --scene-keyword slope=0.012")
    gait.add_argument("--no-sensitivity", action="store_true", help="skip the derivatives w.r.t. the parameters")
    gait.set_defaults(run=_gait)

    solvers = commands.add_parser("solvers", help="the solver presets: order, stages, error estimate, controller")
    solvers.set_defaults(run=_solvers)

    arguments = parser.parse_args(argv)
    return arguments.run(arguments)


if __name__ == "__main__":
    sys.exit(main())
