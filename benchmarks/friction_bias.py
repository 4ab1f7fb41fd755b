"""The pathwise gradient's bias through dry friction: located stick-slip against tanh-regularised friction.

The case of friction beside the walls and stops of `contact_gradient_variance`: there the
first-order (pathwise) gradient is biased where the cost itself jumps; here the question is
the model. `SlidingBlock` on the level (mu_s = 0.5, mu_k = 0.3, g = 9.81, unpushed), blocks
launched at speeds spread over [0.5, 2] m/s, 16 env steps of 0.05 s (all stop within them);
the derivative of each block's stop distance with respect to mu_k, whose closed form is
`-v0^2 / (2 mu_k^2 g)`, by

- `located`: the env's own step (`lerax_like.stick_slip`, Tsit5 at the preset's default
  tolerances): the stop located as an event, then exact rest;
- `tanh`: the friction force `-mu_k N tanh(v / epsilon)` at epsilon = 1e-1, 1e-2, 1e-3
  (`benchmarks.friction.tanh_distances`), Tsit5 at rtol 1e-12, atol 1e-14 (so that the
  bias below is the model's, not the solver's);

each by reverse-mode and forward-mode AD (`jax.jacrev`, `jax.jacfwd`, per block) and by central
differences of the same model (step 1e-5 mu_k). The bias is the largest relative distance
from the closed form; `ad_against_differences` how far the AD is from its own model's
differences (the gradient is the model's exact derivative: what differs is the model).

    python -m benchmarks.friction_bias                 # 16 blocks, into benchmarks/results/
    python -m benchmarks.friction_bias --quick         # 4 blocks, into results/quick/
    python -m benchmarks.friction_bias --figure docs/figures/friction_gradient_bias.png
"""

import argparse
import csv
import json
import pathlib

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

from benchmarks import results_dir  # noqa: E402
from benchmarks.friction import G, MU_K, located_distances, tanh_distances  # noqa: E402
from lerax_like.integrate import make_integrator  # noqa: E402


SHARPNESS = (1e-1, 1e-2, 1e-3)
STEPS = 16
RELATIVE_STEP = 1e-5


def models(forward: bool = False):
    """`(name, epsilon, distances(mu_k, speeds) -> (distances, solver_ok))` of every model;
    with `forward`, each with diffrax's forward-mode adjoint (for `jax.jacfwd`)."""
    adjoint = diffrax.ForwardMode() if forward else None
    tight = make_integrator(
        "tsit5", diffrax.PIDController(rtol=1e-12, atol=1e-14), max_steps=100_000, adjoint=adjoint
    )
    entries = [("located", 0.0, lambda m, s: located_distances(m, s, STEPS, "forward" if forward else None))]
    for epsilon in SHARPNESS:
        entries.append(("tanh", epsilon, lambda m, s, e=epsilon: tanh_distances(m, s, STEPS, e, tight)))
    return entries


def bias_rows(speeds) -> list[dict]:
    """One row per model: its stop distances' and derivatives' largest relative errors."""
    speeds = jnp.asarray(speeds, jnp.float64)
    mu = jnp.asarray(MU_K, jnp.float64)
    v0 = np.asarray(speeds)
    distance = v0**2 / (2 * MU_K * G)
    derivative = -(v0**2) / (2 * MU_K**2 * G)
    rows = []
    for (name, epsilon, distances), (_, _, forward_distances) in zip(models(), models(forward=True)):
        values = jax.jit(distances)
        reverse = jax.jit(jax.jacrev(lambda m, s, d=distances: d(m, s)[0]))(mu, speeds)
        forward = jax.jit(jax.jacfwd(lambda m, s, d=forward_distances: d(m, s)[0]))(mu, speeds)
        h = RELATIVE_STEP * MU_K
        (above, ok_above), (below, ok_below) = values(mu + h, speeds), values(mu - h, speeds)
        differences = (np.asarray(above) - np.asarray(below)) / (2 * h)
        positions, ok = values(mu, speeds)
        relative = lambda a, b: float(np.max(np.abs(np.asarray(a) - b) / np.abs(b)))
        rows.append({
            "model": name,
            "epsilon": epsilon,
            "blocks": len(v0),
            "steps": STEPS,
            "distance_relative_error": relative(positions, distance),
            "reverse_bias": relative(reverse, derivative),
            "forward_bias": relative(forward, derivative),
            "differences_bias": relative(differences, derivative),
            "ad_against_differences": relative(reverse, differences),
            "solver_ok": bool(jnp.all(ok) & jnp.all(ok_above) & jnp.all(ok_below)),
        })
        print(json.dumps(rows[-1]), flush=True)
    return rows


def plot_bias(rows, path) -> None:
    """Relative bias of d(distance)/d(mu_k) against the sharpness, the located model as a line."""
    from lerax_like.analysis.recording import finish_figure, pyplot

    plt = pyplot()
    figure, axis = plt.subplots(figsize=(6.4, 4.4))
    smooth = [row for row in rows if row["model"] == "tanh"]
    epsilons = [row["epsilon"] for row in smooth]
    floor = 1e-17  # an error of exactly zero drawn at the axis' foot
    axis.loglog(epsilons, [max(row["reverse_bias"], floor) for row in smooth], "o-", label="tanh: reverse-mode AD")
    axis.loglog(epsilons, [max(row["differences_bias"], floor) for row in smooth], "x--", ms=9,
                label="tanh: central differences of the same model")
    axis.loglog(epsilons, [max(row["distance_relative_error"], floor) for row in smooth], "s:", color="grey",
                label="tanh: stop distance error")
    for row in rows:
        if row["model"] == "located":
            axis.axhline(max(row["reverse_bias"], floor), color="C2",
                         label=f"located: reverse-mode AD ({row['reverse_bias']:.1e})")
    axis.set_xlabel("tanh sharpness epsilon (m/s)")
    axis.set_ylabel("largest relative error against the closed form")
    axis.grid(True, which="both", alpha=0.3)
    axis.legend(fontsize="small")
    finish_figure(figure, "d(stop distance)/d(mu_k): located friction against tanh", path)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    parser.add_argument("--figure", type=pathlib.Path, default=None, help="also write the figure here")
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    rows = bias_rows(np.linspace(0.5, 2.0, 4 if args.quick else 16))
    with open(out / "friction_bias.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    for path in (out / "friction_bias.png", args.figure):
        if path is not None:
            plot_bias(rows, path)


if __name__ == "__main__":
    main()
