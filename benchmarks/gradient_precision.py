"""float32 against float64 gradients through the simulator: the horizon at which float32 loses the leading digit, per scene.

The cases of `benchmarks/gradient_variance.py` (the smooth cart-pole with Euler and RK4,
the chaotic double cart-pole with RK4, the cart-pole with end stops with Tsit5), at the
nominal `theta` of each policy: the gradient of the rollout cost over each horizon of a
grid, in float32 and in float64, one reverse pass each
(`lerax_like.analysis.gradient_variance.precision_at_horizons`). `gradient_variance` finds
the digit loss at every horizon for the fixed-step cases (its `float32_*` columns); through
adaptive solves that costs minutes per policy, so the end stops are measured here, on the
grid, at three tolerance pairs of Tsit5's step-size controller: the study's (rtol 1e-6,
atol 1e-9) and two that float32 can meet more easily. The fixed-step cases are repeated on
the grid as a check of the study's numbers by a second code path.

    python -m benchmarks gradient_precision            # writes benchmarks/results/gradient_precision.{csv,json}
    python -m benchmarks gradient_precision --quick    # the smooth cart-pole and one end-stop case, short horizons
"""

import time

import diffrax
import jax

jax.config.update("jax_enable_x64", True)

from benchmarks import benchmark_parser, output_folder  # noqa: E402
from lerax_like.analysis.gradient_variance import (  # noqa: E402
    GradientVarianceConfig,
    build_env,
    initial_state,
    nominal_gain,
    precision_at_horizons,
)
from lerax_like.analysis.recording import environment_record, write_csv, write_record  # noqa: E402

HORIZONS = (2, 5, 10, 20, 50, 100, 200, 400)
TOLERANCES = ((1e-6, 1e-9), (1e-5, 1e-7), (1e-4, 1e-6))
"""Tsit5's (rtol, atol) for the end stops: the study's first."""


def cases(quick: bool):
    """`(config, solver, policy, rtol, atol)`; rtol and atol are None for fixed steps."""
    smooth = GradientVarianceConfig.default("CartPoleContinuous", solvers=("euler", "rk4"), sigmas=(0.05,))
    chaotic = GradientVarianceConfig.default("DoubleCartPole", solvers=("rk4",), sigmas=(0.01,))
    fixed = [(smooth, "euler"), (smooth, "rk4")] if quick else [(smooth, "euler"), (smooth, "rk4"), (chaotic, "rk4")]
    for config, solver in fixed:
        for policy in config.policies:
            yield config, solver, policy, None, None
    stops = [(1e4, {})] if quick else [(1e4, {}), (1e6, {}), (1e6, {"end_stop_damping": 0.0})]
    for stiffness, extra in stops:
        for rtol, atol in TOLERANCES[:1] if quick else TOLERANCES:
            name = f"CartPoleContinuous[end_stop_stiffness={stiffness:g}" + "".join(
                f",{key}={value:g}" for key, value in extra.items()) + "]"
            controller = diffrax.PIDController(rtol=rtol, atol=atol)
            config = GradientVarianceConfig.default(
                "CartPoleContinuous", case=name, solvers=("tsit5",), sigmas=(0.05,), policies=("open_loop",),
                scene_kwargs={"end_stop_stiffness": stiffness, **extra, "stepsize_controller": controller},
            )
            yield config, "tsit5", "open_loop", rtol, atol


def main(argv=None):
    arguments = benchmark_parser(__doc__, quick="fewer cases, horizons up to 50").parse_args(argv)
    out = output_folder(arguments)
    horizons = tuple(h for h in HORIZONS if h <= 50) if arguments.quick else HORIZONS
    rows, gains = [], {}
    start = time.perf_counter()
    for config, solver, policy, rtol, atol in cases(arguments.quick):
        began = time.perf_counter()
        envs = {}
        for dtype in ("float64", "float32"):
            env = build_env(config.scene, config.scene_kwargs, solver, dtype)
            envs[dtype] = (env, initial_state(env, config.initial_state, config.seed))
        if (config.name, solver) not in gains:  # the LQR gain takes a Riccati iteration
            gains[config.name, solver] = nominal_gain(
                envs["float64"][0], config.feedback_gain, config.state_weight, config.action_weight
            )
        result = precision_at_horizons(
            envs, solver, policy, gains[config.name, solver], horizons,
            state_weight=config.state_weight, action_weight=config.action_weight,
        )
        for index, horizon in enumerate(result["horizons"]):
            rows.append({
                "case": config.name, "solver": solver, "rtol": rtol or "", "atol": atol or "", "policy": policy,
                "horizon": horizon, "relative_error": result["relative_error"][index],
                "float64_solves_ok": result["float64_solves_ok"][index],
                "float32_solves_ok": result["float32_solves_ok"][index],
                "first_digit_lost_horizon": result["first_digit_lost_horizon"] or "",
            })
        tolerance = "" if rtol is None else f" rtol={rtol:g} atol={atol:g}"
        errors = " ".join(f"{e:.1e}" for e in result["relative_error"])
        print(f"{config.name} {solver}{tolerance} {policy}: relative errors {errors}; leading digit lost at "
              f"{result['first_digit_lost_horizon']}; float32 solves ok {result['float32_solves_ok']} "
              f"({time.perf_counter() - began:.0f} s)", flush=True)
    # Errors in Python's shortest round-trip form, as the file has always held them.
    write_csv(rows, out / "gradient_precision.csv", cell=str)
    record = {
        "horizons": list(horizons),
        "dt": float(build_env("CartPoleContinuous", {}, "euler", "float64").dt),
        "definition": "relative error = |g32 - g64| / |g64| of the gradient of the rollout cost over the horizon at "
                      "the nominal theta; the leading digit is lost where it exceeds 0.1 (first such horizon of the grid)",
        "seconds": round(time.perf_counter() - start, 1),
        "environment": environment_record(),
    }
    write_record(record, out / "gradient_precision.json")
    print(f"wrote {out / 'gradient_precision.csv'}, {out / 'gradient_precision.json'}")


if __name__ == "__main__":
    main()
