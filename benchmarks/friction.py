"""Located stick-slip against regularised (tanh) Coulomb friction: forward and gradient cost, at matched accuracy.

`SlidingBlock` on the level (mu_s = 0.5, mu_k = 0.3, g = 9.81, unpushed), N envs launched at
speeds spread over [0.5, 2] m/s, T env steps of 0.05 s (long enough for all to stop), Tsit5
at the preset's default tolerances (rtol 1e-6, atol 1e-9) in both models:

- `located`: the env's own step (`lerax_like.stick_slip`): slip, the stop located as an
  event, then exact rest;
- `tanh`: the friction force `-mu_k N tanh(v / epsilon)`, integrated through with the same
  integrator (`Integrator.integrate`, as a smooth scene's step), at the largest `epsilon`
  of a sweep (1e-1 ... 1e-7) whose stop distances after T steps are all within 1e-3
  (relative) of the closed form `v0^2 / (2 mu_k g)`, which the located model meets to 1e-10.

Throughput is env steps per second (N T over the median of `--repeats` runs after
compiling, the four programs interleaved in each repeat) of the rollout, and of the value
and gradient of the summed stop distance with respect to mu_k (reverse mode). Also
recorded: each model's largest relative error of the distance and of its derivative
`-v0^2 / (2 mu_k^2 g)` against the closed forms.

    python -m benchmarks friction            # N = 1024, T = 16
    python -m benchmarks friction --quick    # N = 64, into results/quick/
"""

import argparse
import csv
import json
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402
from benchmarks import results_dir  # noqa: E402
from benchmarks._workload import interleaved  # noqa: E402


MU_S, MU_K, G = 0.5, 0.3, 9.81
SHARPNESS = tuple(10.0 ** -k for k in range(1, 8))


def make_env():
    return ll.make("SlidingBlock", static_friction=MU_S, kinetic_friction=MU_K, gravity=G)


def _start(v0):
    return ll.EnvState(y=jnp.stack([jnp.zeros_like(v0), v0]), steps=jnp.zeros((), dtype=int))


def located_distances(mu_k, speeds, steps, adjoint=None):
    """The stop positions of the env's own (located) step; `adjoint` as `with_adjoint` takes it ("forward")."""
    env = eqx.tree_at(lambda e: e.friction[0].kinetic_friction, make_env(), mu_k)
    if adjoint is not None:
        env = ll.with_adjoint(env, adjoint)

    def one(v0):
        ys, info = ll.rollout(env, _start(v0), jnp.zeros((steps, 1)))
        return ys[-1, 0], jnp.all(info["solver_ok"])

    return jax.vmap(one)(speeds)


def tanh_distances(mu_k, speeds, steps, epsilon, integrator=None):
    """The same blocks under `-mu_k N tanh(v / epsilon)`, integrated by `integrator` (the env's by default)."""
    env = make_env()
    block = env.dynamics
    integrator = integrator or env.integrator

    def field(t, y, u):
        del u
        normal = block.mass * block.gravity * jnp.cos(block.incline)
        friction = -mu_k * normal * jnp.tanh(y[1] / epsilon)
        return block.forced_vector_field(t, y, jnp.zeros(1, y.dtype), jnp.stack([friction]))

    def one(v0):
        def step(y, _):
            after, info = integrator.integrate(field, y, jnp.zeros(1, y.dtype), env.dt)
            return after, info["solver_ok"]

        y, ok = jax.lax.scan(step, jnp.stack([jnp.zeros_like(v0), v0]), None, length=steps)
        return y[0], jnp.all(ok)

    return jax.vmap(one)(speeds)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    parser.add_argument("--envs", type=int, default=None)
    parser.add_argument("--steps", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    envs = args.envs or (64 if args.quick else 1024)
    speeds = jnp.linspace(0.5, 2.0, envs)
    distance = np.asarray(speeds) ** 2 / (2 * MU_K * G)
    derivative = -np.asarray(speeds) ** 2 / (2 * MU_K**2 * G)
    mu = jnp.asarray(MU_K)

    # The sharpness: the largest epsilon whose distances (on 16 of the speeds) are within 1e-3
    # (a sharper one only costs more steps).
    probe = speeds[:: max(1, envs // 16)]
    sweep, epsilon = [], None
    for value in SHARPNESS:
        positions, ok = jax.jit(lambda m, s, value=value: tanh_distances(m, s, args.steps, value))(mu, probe)
        error = float(np.max(np.abs(np.asarray(positions) - np.asarray(probe) ** 2 / (2 * MU_K * G)) / (np.asarray(probe) ** 2 / (2 * MU_K * G))))
        sweep.append({"epsilon": value, "distance_relative_error": error, "solver_ok": bool(jnp.all(ok))})
        print(json.dumps(sweep[-1]), flush=True)
        if error <= 1e-3 and bool(jnp.all(ok)):
            epsilon = value
            break
    with open(out / "friction_sweep.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(sweep[0]))
        writer.writeheader()
        writer.writerows(sweep)
    if epsilon is None:
        raise SystemExit("no sharpness in the sweep matches the stop distance within 1e-3")

    models = {
        "located": lambda m, s: located_distances(m, s, args.steps),
        "tanh": lambda m, s: tanh_distances(m, s, args.steps, epsilon),
    }
    programs, rows = {}, []
    for name, distances in models.items():
        forward = jax.jit(distances)
        gradient = jax.jit(jax.value_and_grad(lambda m, s, distances=distances: jnp.sum(distances(m, s)[0])))
        positions, ok = jax.block_until_ready(forward(mu, speeds))  # compiles
        jax.block_until_ready(gradient(mu, speeds))
        # Each env's derivative (the gradient of the sum is their sum): the Jacobian.
        per_env = jax.jit(jax.jacrev(lambda m, s, distances=distances: distances(m, s)[0]))(mu, speeds)
        programs[f"{name} forward"] = lambda forward=forward: jax.block_until_ready(forward(mu, speeds))
        programs[f"{name} gradient"] = lambda gradient=gradient: jax.block_until_ready(gradient(mu, speeds))
        rows.append({
            "model": name, "epsilon": epsilon if name == "tanh" else 0.0, "envs": envs, "steps": args.steps,
            "distance_relative_error": float(np.max(np.abs(np.asarray(positions) - distance) / distance)),
            "derivative_relative_error": float(np.max(np.abs(np.asarray(per_env) - derivative) / np.abs(derivative))),
            "solver_ok_fraction": float(jnp.mean(ok)),
        })
    # Interleaved, so that the load of the shared machine falls on both models alike.
    seconds = interleaved(programs, args.repeats)
    for row in rows:
        row["forward_steps_per_s"] = envs * args.steps / float(np.median(seconds[f"{row['model']} forward"]))
        row["value_and_grad_steps_per_s"] = envs * args.steps / float(np.median(seconds[f"{row['model']} gradient"]))
        print(json.dumps(row), flush=True)
    with open(out / "friction.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    located, smooth = rows
    print(json.dumps({
        "forward_ratio": located["forward_steps_per_s"] / smooth["forward_steps_per_s"],
        "value_and_grad_ratio": located["value_and_grad_steps_per_s"] / smooth["value_and_grad_steps_per_s"],
    }), flush=True)


if __name__ == "__main__":
    main()
