"""Peak memory and time of the gradient of a 1000-step rollout: storing every step vs checkpointing.

The rollout is a `lax.scan` of env steps, vmapped over 256 envs (CartPoleContinuous; each step a diffrax solve with
its own RecursiveCheckpointAdjoint). Reverse mode through the scan stores every step's
intermediate values ("store every step"). Checkpointing stores only the state between
steps and recomputes each step's internals on the backward pass ("checkpoint every
step": `jax.checkpoint` on the scan body), or stores the state only every 40 steps and
recomputes a whole segment ("checkpoint segments", of 40 steps).

Memory is XLA's own accounting of the compiled gradient (`memory_analysis()`: temporary
buffers, i.e. the peak working set beyond inputs and outputs); time is the median of 5
runs after compilation.

    python -m benchmarks gradient_memory            # writes benchmarks/results/gradient_memory.json
    python -m benchmarks gradient_memory --quick    # 120 steps, 8 envs, into results/quick/
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402  (after float64 is on)
from benchmarks import benchmark_parser, output_folder  # noqa: E402
from lerax_like.analysis.recording import write_record  # noqa: E402
from lerax_like.env import EnvState  # noqa: E402

STEPS = 1000
SEGMENT = 40
BATCH = 256  # vmapped envs: a state of 4 numbers alone makes every method's memory negligible


def step(env, y, action):
    state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
    return env.transition(state, action, key=jr.key(0))[0].y


def loss_store(env, y0, actions):
    def body(y, action):
        y = step(env, y, action)
        return y, jnp.cos(y[2])

    return jnp.sum(jax.lax.scan(body, y0, actions)[1])


def loss_checkpoint_every_step(env, y0, actions):
    @jax.checkpoint
    def body(y, action):
        y = step(env, y, action)
        return y, jnp.cos(y[2])

    return jnp.sum(jax.lax.scan(body, y0, actions)[1])


def loss_checkpoint_segments(env, y0, actions):
    def inner(y, action):
        y = step(env, y, action)
        return y, jnp.cos(y[2])

    @jax.checkpoint
    def segment(y, segment_actions):
        y, values = jax.lax.scan(inner, y, segment_actions)
        return y, jnp.sum(values)

    return jnp.sum(jax.lax.scan(segment, y0, actions.reshape(-1, SEGMENT, 1))[1])


def measure(loss, env, y0s, actions, solver):
    params, static = eqx.partition(env, eqx.is_array)

    def batch_loss(params, y0s):
        env = eqx.combine(params, static)
        return jnp.sum(jax.vmap(loss, in_axes=(None, 0, None))(env, y0s, actions))

    compiled = jax.jit(jax.grad(batch_loss)).lower(params, y0s).compile()
    memory = compiled.memory_analysis()
    g = jax.block_until_ready(compiled(params, y0s))
    times = []
    for _ in range(5):
        start = time.perf_counter()
        jax.block_until_ready(compiled(params, y0s))
        times.append(time.perf_counter() - start)
    return {
        "solver": solver,
        "temp_bytes": int(memory.temp_size_in_bytes),
        "seconds": float(np.median(times)),
        "grad_pole_mass": float(g.dynamics.pole_mass),
    }


def main(argv=None):
    arguments = benchmark_parser(__doc__, quick="120 steps, 8 envs").parse_args(argv)
    out = output_folder(arguments)
    steps, batch = (3 * SEGMENT, 8) if arguments.quick else (STEPS, BATCH)  # a whole number of segments
    actions = 0.5 * jnp.sin(0.05 * jnp.arange(steps, dtype=jnp.float64))[:, None]
    y0s = jnp.stack([jnp.array([0.0, 0.0, 0.3, 0.0])] * batch) + 0.01 * jr.normal(jr.key(0), (batch, 4))
    rows = []
    for solver in ("euler", "rk4", "tsit5"):
        env = ll.make("CartPoleContinuous", reward="smooth", solver=solver, theta_threshold_radians=float("inf"), x_threshold=float("inf"))
        for name, loss in [
            ("store every step", loss_store),
            ("checkpoint every step", loss_checkpoint_every_step),
            (f"checkpoint segments of {SEGMENT}", loss_checkpoint_segments),
        ]:
            row = {"method": name, "steps": steps, **measure(loss, env, y0s, actions, solver)}
            rows.append(row)
            print(f"{solver:>6} {name:>26}: {row['temp_bytes'] / 2**20:8.2f} MiB temp, {row['seconds'] * 1e3:8.1f} ms, "
                  f"dL/d pole_mass = {row['grad_pole_mass']:.12g}")
    write_record({"rows": rows, "batch": batch, "jax": jax.__version__, "backend": jax.default_backend()},
                 out / "gradient_memory.json")


if __name__ == "__main__":
    main()
