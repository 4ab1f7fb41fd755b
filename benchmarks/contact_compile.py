"""Compile time of gradient programs through located contact and friction, beside the same cart-pole without them.

What a check of a gradient through events costs is what its program costs to build, not to run
(docs/testing.md, "Where the time goes"). Per row, one fresh `jax.jit` (new closures, so no cache
is hit) of a loss over `CartPoleContinuous`, 4 envs from distinct resets (`jax.vmap`) x 12 env
steps pushed at 0.3 N: `value` (the loss), `reverse` (`jax.grad` with respect to every
dynamics parameter), `forward` (`jax.jvp` along `pole_mass`, `ll.with_adjoint(env,
"forward")`). Scenes: `smooth` (the floor: the same dynamics and integrator with no events),
`walls` (located walls 6 cm either side, restitution 0.8) and `friction` (Coulomb friction of
the cart, static 0.3, kinetic 0.15: located stick-slip switches). Reported: trace + lowering
and XLA compilation, wall-clock, of the fastest of fresh repeats (the first in a process
traces cold), and its total against the smooth row's (`vs_smooth`).

    python -m benchmarks contact_compile            # Euler and Tsit5, 3 repeats
    python -m benchmarks contact_compile --quick    # Euler, 1 repeat, into results/quick/
"""

import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

jax.config.update("jax_enable_x64", True)

import lerax_like as ll
from benchmarks import benchmark_parser, output_folder
from lerax_like.analysis.recording import write_csv

ENVS, STEPS = 4, 12
SCENES = {
    "smooth": {},
    "walls": {"restitution": 0.8, "track_limit": 0.06},
    "friction": {"cart_static_friction": 0.3, "cart_kinetic_friction": 0.15, "pole_mass": 0.3},
}


def program(scene: str, solver: str, kind: str):
    """A fresh jitted function of the env's arrays and its arguments."""
    env = ll.make("CartPoleContinuous", solver=solver, x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, **SCENES[scene])
    if kind == "forward":
        env = ll.with_adjoint(env, "forward")
    states = jax.vmap(lambda key: env.reset(key=key)[0])(jr.split(jr.key(0), ENVS))
    actions = jnp.full((ENVS, STEPS, 1), 0.3)
    arrays, static = eqx.partition(env, eqx.is_inexact_array)

    def loss(arrays):
        env = eqx.combine(arrays, static)
        ys = jax.vmap(lambda state, acts: ll.rollout(env, state, acts)[0])(states, actions)
        return jnp.sum(ys**2)

    along = eqx.tree_at(lambda e: e.dynamics.pole_mass, jax.tree.map(jnp.zeros_like, arrays), jnp.ones(()))
    function = {
        "value": loss,
        "reverse": jax.grad(loss),
        "forward": lambda arrays: jax.jvp(loss, (arrays,), (along,)),
    }[kind]
    return jax.jit(lambda arrays: function(arrays)), arrays


def measure(scene: str, solver: str, kind: str) -> dict[str, float]:
    jitted, arrays = program(scene, solver, kind)
    start = time.perf_counter()
    lowered = jitted.lower(arrays)
    traced = time.perf_counter() - start
    start = time.perf_counter()
    lowered.compile()
    compiled = time.perf_counter() - start
    return {"trace_lower_s": traced, "compile_s": compiled, "total_s": traced + compiled}


def main(argv=None):
    parser = benchmark_parser(__doc__, quick="Euler, 1 repeat")
    parser.add_argument("--repeats", type=int, default=None)
    args = parser.parse_args(argv)
    solvers = ["euler"] if args.quick else ["euler", "tsit5"]
    repeats = args.repeats or (1 if args.quick else 3)
    out = output_folder(args)
    print(f"{ENVS} envs x {STEPS} steps, the fastest of {repeats} fresh compiles, load average {os.getloadavg()}")
    rows = []
    for solver in solvers:
        for kind in ("value", "reverse", "forward"):
            smooth = None
            for scene in SCENES:
                best = min((measure(scene, solver, kind) for _ in range(repeats)), key=lambda times: times["total_s"])
                smooth = best["total_s"] if scene == "smooth" else smooth
                row = {"solver": solver, "program": kind, "scene": scene, **best, "vs_smooth": best["total_s"] / smooth}
                rows.append(row)
                print(f"{solver:6s} {kind:8s} {scene:9s} trace+lower {best['trace_lower_s']:6.2f} s  "
                      f"compile {best['compile_s']:6.2f} s  total {best['total_s']:6.2f} s  ({row['vs_smooth']:.1f}x smooth)", flush=True)
    write_csv(rows, out / "contact_compile.csv", cell=lambda v: f"{v:.4f}" if isinstance(v, float) else v)


if __name__ == "__main__":
    main()
