"""Gradient variance and bias through contact: located walls beside penalty end stops.

The study of `lerax_like.analysis.gradient_variance` (Suh et al., ICML 2022) on the
cart-pole running into the end of its rail at 1 m/s from 0.09 m (the nominal impact at
0.09 s, halfway between the cost's sampling instants), Tsit5, sigma 0.05, 512 samples per
estimator and 8192 antithetic samples for the reference, float64:

- walls at 0.5 m located as events, restitution 0.8 (open loop and linear feedback);
- penalty end stops of 1e4 and 1e6 N/m at the same place (open loop);
- the walls again from 0.1 m, where the nominal impact falls on the sampling instant
  0.10 s: the cost reads the state at each step's end, which jumps through an impact, so
  the cost itself is discontinuous where the smoothing samples straddle the instant, and
  any pathwise gradient (exact as it is) is biased there.

    python -m benchmarks contact_gradient_variance           # benchmarks/results/contact_gradient_variance*.{csv,json,png}
    python -m benchmarks contact_gradient_variance --quick   # 64 samples, horizon 10, into results/quick/
"""

import jax

jax.config.update("jax_enable_x64", True)

from benchmarks import benchmark_parser, output_folder  # noqa: E402
from benchmarks.gradient_variance import run  # noqa: E402
from lerax_like.analysis.gradient_variance import GradientVarianceConfig  # noqa: E402
from lerax_like.analysis.recording import finish_figure, pyplot, read_csv_rows  # noqa: E402

FULL = dict(horizons=(10, 20, 50), samples=512, reference_samples=8192)
QUICK = dict(horizons=(10,), samples=64, reference_samples=1024)


def configs(quick: bool = False):
    sizes = QUICK if quick else FULL
    # No Lyapunov exponent and no float32 comparison: the question here is the bias.
    common = dict(sigmas=(0.05,), lyapunov=False, precision=False, **sizes)

    def case(scene_kwargs, **overrides):
        settings = {**common, "policies": ("open_loop",), **overrides}
        return GradientVarianceConfig.default("CartPoleContinuous", scene_kwargs=scene_kwargs, **settings)

    walls = case({"restitution": 0.8}, policies=("open_loop", "linear_feedback"))
    on_the_instant = case(
        {"restitution": 0.8}, initial_state=(0.4, 1.0, 0.0, 0.0),
        case="CartPoleContinuous[restitution=0.8,impact on a sampling instant]",
    )
    if quick:
        return [walls, case({"end_stop_stiffness": 1e4})]
    return [walls, case({"end_stop_stiffness": 1e4}), case({"end_stop_stiffness": 1e6}), on_the_instant]


def plot_bias(csv_path, path) -> None:
    """The first-order bias (solid) and the standard error noise alone gives it (thin)
    against the horizon, one colour per case and policy, from the recorded CSV."""
    plt = pyplot()
    rows = [row for row in read_csv_rows(csv_path) if row["estimator"] == "first_order"]
    figure, axis = plt.subplots(figsize=(8, 4.8))
    lines = dict.fromkeys((row["case"], row["policy"]) for row in rows)
    for index, (case, policy) in enumerate(lines):
        line = sorted((int(r["horizon"]), float(r["bias"]), float(r["bias_standard_error"]))
                      for r in rows if r["case"] == case and r["policy"] == policy)
        horizons, bias, error = zip(*line)
        label = case.replace("CartPoleContinuous", "").strip("[]") + f", {policy}"
        axis.plot(horizons, bias, marker="o", color=f"C{index}", label=label)
        axis.plot(horizons, error, lw=0.8, ls="--", color=f"C{index}")
    axis.set_yscale("log")
    axis.set_xlabel("horizon (env steps of 0.02 s)")
    axis.set_ylabel("|first order - reference| (dashed: noise alone)")
    axis.grid(True, alpha=0.3)
    axis.legend(fontsize="small")
    finish_figure(figure, "Bias of the gradient through the simulator: located walls against penalty stops", path)


def main(argv=None):
    arguments = benchmark_parser(__doc__, quick="64 samples, horizon 10, walls and 1e4 N/m stops").parse_args(argv)
    out = output_folder(arguments)
    run(configs(arguments.quick), out, "contact_gradient_variance")
    plot_bias(out / "contact_gradient_variance.csv", out / "contact_gradient_variance_bias.png")


if __name__ == "__main__":
    main()
