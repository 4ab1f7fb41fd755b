"""Gradient error against run time, per solver and step: work-precision for gradients.

Loss: sum of cos(theta) along a 2 s open-loop swing of CartPoleContinuous (no
termination) from 0.5 rad, gradient with respect to the four physical parameters. Reference: Dopri8 at rtol 1e-12. Also: the sign of d theta(t) / d
half_length under Euler at dt = 0.02 (Gymnasium's integrator) against the reference.

    python benchmarks/gradient_error.py   # writes benchmarks/results/gradient_error.{json,png}
"""

import json
import pathlib
import sys

import diffrax
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

jax.config.update("jax_enable_x64", True)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

import lerax_like as ll  # noqa: E402
from lerax_like.analysis.gradient_accuracy import (  # noqa: E402
    gradient_work_precision,
    reference_integrator,
    trajectory_sensitivity,
    with_integrator,
)
from lerax_like.env import EnvState  # noqa: E402

RESULTS = pathlib.Path(__file__).parent / "results"
INF = float("inf")
STEPS = 100
Y0 = jnp.array([0.0, 0.0, 0.5, 0.0])
ACTIONS = 0.5 * jnp.sin(0.1 * jnp.arange(STEPS, dtype=jnp.float64))[:, None]


def loss(tree):
    env, y0 = tree
    ys, _ = ll.rollout(env, EnvState(y=y0, steps=jnp.zeros((), dtype=int)), ACTIONS, key=jr.key(0))
    return jnp.sum(jnp.cos(ys[:, 2]))


def main():
    env = ll.CartPoleContinuous(reward="smooth", theta_threshold_radians=INF, x_threshold=INF)
    integrators = []
    for preset in ("euler", "midpoint", "rk4"):
        for substeps in (1, 2, 4, 8, 16, 32):
            integrators.append((preset, ll.make_integrator(preset, substeps=substeps)))
    for preset in ("tsit5", "dopri5", "kvaerno5"):
        for rtol in (1e-3, 1e-5, 1e-7, 1e-9):
            controller = diffrax.PIDController(rtol=rtol, atol=rtol * 1e-3)
            integrators.append((preset, ll.make_integrator(preset, controller)))

    rows = gradient_work_precision(env, lambda e: loss((e, Y0)), lambda e: e.dynamics, integrators)
    for row in rows[:-1]:
        print(f"{row['label']:>9} substeps={row['steps_per_env_step']:>2} rtol={row['rtol']:.0e} "
              f"error={row['error']:.2e} time={row['seconds'] * 1e3:.2f} ms")

    # Wrong sign: d theta_k / d half_length along a 5 s swing, Euler at dt = 0.02 vs reference.
    long_actions = 0.5 * jnp.sin(0.1 * jnp.arange(250, dtype=jnp.float64))[:, None]
    half_length = lambda e: e.dynamics.half_length
    euler = np.asarray(trajectory_sensitivity(env, half_length, Y0, long_actions)[:, 2])
    exact = np.asarray(
        trajectory_sensitivity(with_integrator(env, reference_integrator()), half_length, Y0, long_actions)[:, 2]
    )
    wrong = np.nonzero(np.sign(euler) != np.sign(exact))[0]
    big = [int(k) for k in wrong if min(abs(euler[k]), abs(exact[k])) > 0.2 * np.abs(exact).max()]
    k = big[0] if big else None
    sign = {
        "loss": "theta after k env steps (dt = 0.02) of the open-loop swing from 0.5 rad",
        "parameter": "half_length",
        "first_wrong_sign_step_with_both_magnitudes_above_20pct_of_max": k,
        "euler_dt_0.02": float(euler[k]) if k is not None else None,
        "reference": float(exact[k]) if k is not None else None,
        "fraction_of_steps_with_wrong_sign": float(len(wrong) / len(exact)),
    }
    print(json.dumps(sign, indent=1))

    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "gradient_error.json").write_text(
        json.dumps({"rows": rows, "wrong_sign": sign, "jax": jax.__version__, "backend": jax.default_backend()}, indent=1)
    )

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(15, 4.2))
    labels = sorted({r["label"] for r in rows[:-1]}, key=[r["label"] for r in rows].index)
    for label in labels:
        group = [r for r in rows[:-1] if r["label"] == label]
        errors = [max(r["error"], 1e-16) for r in group]
        if np.isnan(group[0]["rtol"]):
            left.loglog([0.02 / r["steps_per_env_step"] for r in group], errors, "o-", label=label)
        else:
            left.loglog([r["rtol"] for r in group], errors, "s--", label=f"{label} (x: rtol)")
        right.loglog([r["seconds"] * 1e3 for r in group], errors, "o-", label=label)
    left.set_xlabel("solver step (s), or rtol for adaptive")
    left.set_ylabel("relative gradient error vs Dopri8 rtol 1e-12")
    left.set_title("gradient error per solver and step")
    left.legend(fontsize=8)
    right.set_xlabel("time of one gradient (ms)")
    right.set_title("gradient work-precision")
    right.legend(fontsize=8)
    t = 0.02 * np.arange(1, len(exact) + 1)
    middle.plot(t, exact, label="continuous (reference)")
    middle.plot(t, euler, label="Euler, dt = 0.02")
    middle.axhline(0, color="k", lw=0.5)
    if k is not None:
        middle.axvline(t[k], color="r", ls=":", label=f"wrong sign at step {k}")
    middle.set_xlabel("t (s)")
    middle.set_ylabel("d theta(t) / d half_length")
    middle.set_title("sensitivity along a swing")
    middle.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "gradient_error.png", dpi=110)


if __name__ == "__main__":
    main()
