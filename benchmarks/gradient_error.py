"""Gradient error against run time, per solver and step: work-precision for gradients.

Loss: sum of cos(theta) along a 2 s open-loop swing of CartPoleContinuous from 0.5 rad,
gradient (`jax.grad`) with respect to the four physical parameters of Gymnasium's
cart-pole. Reference: Dopri8 at rtol 1e-12. Also: the sign of d theta(t) / d half_length
under Euler at dt = 0.02 (Gymnasium's integrator) against the reference, along 5 s.
The same study as `lerax-like gradients CartPoleContinuous`, with this loss and swing.

    python -m benchmarks gradient_error            # writes benchmarks/results/gradient_error.{csv,json,png}
    python -m benchmarks gradient_error --quick    # the quick study's sweeps, into results/quick/
"""

import json

import jax
import jax.numpy as jnp

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402  (after float64 is on)
from benchmarks import benchmark_parser, output_folder  # noqa: E402
from lerax_like.analysis.gradient_accuracy import GradientStudyConfig, run_gradient_study  # noqa: E402
from lerax_like.gradients import sensitivity_signs  # noqa: E402
from lerax_like.analysis.gradient_accuracy import write_gradient_study  # noqa: E402
from lerax_like.analysis.tables import format_gradient_table  # noqa: E402

STEPS = 100
Y0 = jnp.array([0.0, 0.0, 0.5, 0.0])


def swing(steps):
    """An open-loop push, `0.5 sin(0.1 k)` at env step k."""
    return 0.5 * jnp.sin(0.1 * jnp.arange(steps, dtype=jnp.float64))[:, None]


def sum_cos_theta(ys):
    """Sum of cos(theta) along the rollout."""
    return jnp.sum(jnp.cos(ys[:, 2]))


def main(argv=None):
    arguments = benchmark_parser(__doc__, quick="the quick study's sweeps and repeats").parse_args(argv)
    out = output_folder(arguments)
    config = GradientStudyConfig.default(
        "CartPoleContinuous",
        quick=arguments.quick,
        horizon=STEPS,
        initial_state=Y0,
        actions=swing(STEPS),
        cost=sum_cos_theta,
        parameters=("gravity", "cart_mass", "pole_mass", "half_length"),
        mode="reverse",
    )
    result = run_gradient_study(config)
    print(format_gradient_table(result.rows))

    # Wrong sign: d theta_k / d half_length along a 5 s swing, Euler at dt = 0.02 vs reference.
    env = ll.CartPoleContinuous()
    signs = sensitivity_signs(env, lambda e: e.dynamics.half_length, Y0, swing(250), component=2)
    signs.update(label="Euler, dt = 0.02", quantity="d theta(t) / d half_length")
    step = signs["first_clear_wrong_sign_step"]
    summary = {
        "wrong_sign_fraction": signs["wrong_sign_fraction"],
        "first_clear_wrong_sign_step": step,
        "t": signs["times"][step] if step is not None else None,
        "euler_dt_0.02": signs["sensitivity"][step] if step is not None else None,
        "reference": signs["reference"][step] if step is not None else None,
    }
    print(json.dumps(summary, indent=1))
    paths = write_gradient_study(
        result, out, stem="gradient_error", signs=signs, jax=jax.__version__, backend=jax.default_backend()
    )
    print("wrote " + ", ".join(paths.values()))


if __name__ == "__main__":
    main()
