"""When do the simulator's gradients pay? First- vs zeroth-order gradient estimators against horizon.

The study of Suh et al. (ICML 2022) on three problems, per solver (see
`lerax_like.analysis.gradient_variance`):

- CartPoleContinuous from a 0.1 rad tilt (smooth; Euler, Gymnasium's step, and RK4);
- DoubleCartPole from a 0.05 rad tilt of the first pole (chaotic once it falls; RK4), at
  two smoothing scales;
- the cart-pole with end stops of stiffness 1e4 and 1e6 N/m at 0.5 m (damping ratio
  about 0.1), running into one at 1 m/s (stiff contact; Tsit5, adaptive), and at 1e6
  without the damper. The recorded run started 0.1 m from the stop; the default start is
  now 0.09 m (`CONTACT_GAP`), and `contact_gradient_variance` compares the stops with
  located walls from there.

Horizons 10 to 200 env steps of 0.02 s, an open-loop action sequence and (without end
stops) a linear feedback policy around the LQR gain, 512 samples per estimator and 8192
antithetic samples for the reference, float64; float32 against float64 up to 400 steps
(without end stops).

    python -m benchmarks gradient_variance            # writes benchmarks/results/gradient_variance*.{csv,json,png}
    python -m benchmarks gradient_variance --quick    # the smooth cart-pole only, small sizes, into results/quick/
"""

import time

import jax

jax.config.update("jax_enable_x64", True)

from benchmarks import benchmark_parser, output_folder  # noqa: E402
from lerax_like.analysis.gradient_variance import (  # noqa: E402
    GradientVarianceConfig,
    run_gradient_variance,
    summary,
    write_gradient_variance,
)

COMMON = dict(horizons=(10, 20, 50, 100, 200), samples=512, reference_samples=8192, precision_horizon=400)
QUICK = dict(horizons=(10, 50), samples=64, reference_samples=512, precision_horizon=50)


def configs(quick: bool = False):
    if quick:
        return [GradientVarianceConfig.default("CartPoleContinuous", solvers=("euler", "rk4"), sigmas=(0.05,), **QUICK)]

    def end_stops(stiffness, **overrides):
        # Open loop only, and no float32 comparison: through Tsit5's adaptive solves the
        # reverse-mode Jacobian of the running cost takes minutes per policy on 2 cores.
        settings = dict(solvers=("tsit5",), sigmas=(0.05,), policies=("open_loop",), precision=False, **COMMON)
        settings.update(overrides)
        return GradientVarianceConfig.default(
            "CartPoleContinuous", scene_kwargs={"end_stop_stiffness": stiffness, **settings.pop("scene_kwargs", {})},
            **settings,
        )

    return [
        GradientVarianceConfig.default("CartPoleContinuous", solvers=("euler", "rk4"), sigmas=(0.05,), **COMMON),
        end_stops(1e4),
        end_stops(1e6),
        GradientVarianceConfig.default("DoubleCartPole", solvers=("rk4",), sigmas=(0.01, 0.1), **COMMON),
        # The stiffest stops without their damper: a vector field with a kink at contact
        # instead of a jump (the damper's force c x_dot appears at once on contact).
        end_stops(1e6, scene_kwargs={"end_stop_damping": 0.0},
                  case="CartPoleContinuous[end_stop_stiffness=1e+06,end_stop_damping=0]"),
    ]


def run(configs, out, stem: str) -> None:
    """Run the studies of `configs` in turn, writing `<stem>.{csv,json}` into `out` after
    every one, so that a later failure keeps the finished ones, and the figures
    (`<stem>_<case>.png`) at the end."""
    results = []
    start = time.perf_counter()
    for index, config in enumerate(configs):
        began = time.perf_counter()
        results.append(run_gradient_variance(config, progress=print))
        print(f"{config.name}: {time.perf_counter() - began:.0f} s")
        for entry in summary(results[-1]):
            print(entry)
        paths = write_gradient_variance(
            results, out, stem=stem, plot=index == len(configs) - 1, study_seconds=time.perf_counter() - start,
            jax=jax.__version__, backend=jax.default_backend(),
        )
    print(f"{time.perf_counter() - start:.0f} s; wrote " + ", ".join(paths.values()))


def main(argv=None):
    quick = "the smooth cart-pole only: horizons 10 and 50, 64 samples"
    arguments = benchmark_parser(__doc__, quick=quick).parse_args(argv)
    run(configs(arguments.quick), output_folder(arguments), "gradient_variance")


if __name__ == "__main__":
    main()
