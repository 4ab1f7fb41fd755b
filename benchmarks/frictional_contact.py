"""A disk launched sliding, three ways: located frictional contact against tanh friction and a penalty floor.

A uniform disk (radius 0.1 m, 1 kg, I = m r^2 / 2, g = 9.81) on a floor, launched sliding at
v0 = 2 m/s with no spin, N disks of kinetic coefficients mu spread over [0.25, 0.75], T env
steps of 0.05 s (1 s by default, past the end of every skid). Closed form: the friction force
-mu m g slows the centre and spins the disk up, the slip falls at 3 mu g, pure rolling begins
at t* = v0 / (3 mu g) at speed 2 v0 / 3, and for T > t*

    x(T) = v0^2 / (18 mu g) + 2 v0 T / 3,    dx(T)/dmu = -v0^2 / (18 mu^2 g)

(checked here against the located model, whose error sits at round-off). Three models, all
in JAX with Tsit5 at the preset's tolerances (rtol 1e-6, atol 1e-9), one solve per env step:

- `located`: `RollingDisk` (`lerax_like.floor_contact`): the slip's end located as an event,
  then exact rolling; the floor a constraint;
- `tanh`: the same disk held on the floor (`z` fixed), the friction force `-mu m g tanh(w /
  epsilon)` on the contact point (`w` its slip velocity): one smooth ODE;
- `penalty`: the floor a spring-damper (1e5 N/m, critically damped) pushing on the disk
  where it sinks in, with the same tanh friction on its normal force; the disk placed on it
  touching (no penetration, at rest vertically), so it first settles into the spring.

Measured per model: the largest errors of x(T) and of dx(T)/dmu against the closed form over
the batch, the solver steps per disk, the forward time and the value-and-gradient time of the
batch (`jax.vmap` of `jax.value_and_grad` in mu, reverse mode; the located model in forward
mode too, `with_adjoint(env, "forward")` and `jax.jvp`), each the median of `--repeats`
interleaved runs after compiling (one call where a call takes over 30 s), the compile times,
and XLA's temporary memory of each compiled program (`memory_analysis()`, as `gradient_memory`).

    python -m benchmarks frictional_contact            # N = 256, T = 20
    python -m benchmarks frictional_contact --quick    # N = 16, T = 20, into results/quick/
"""

import json
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402
from benchmarks import output_folder, sized_arguments, write_csv  # noqa: E402
from benchmarks._workload import interleaved  # noqa: E402
from lerax_like.analysis.recording import write_record  # noqa: E402
from lerax_like.physics import DiskFloor  # noqa: E402


V0, RADIUS, G, DT = 2.0, 0.1, 9.81, 0.05
MU_RANGE = (0.25, 0.75)
STIFFNESS = 1e5  # N/m: 0.1 mm of sinking under the disk's weight
DAMPING = 2 * np.sqrt(STIFFNESS * 1.0)  # critical for 1 kg
SHARPNESS = (1e-2, 1e-4)
# Per env step: a tanh of epsilon 1e-4 is stiff (rate 3 mu g / epsilon, up to 2.2e5 /s), so that
# an explicit Tsit5 takes thousands of steps in each env step.
MAX_STEPS = 100_000
LONG = 30.0  # s


def closed_form(mu, seconds):
    return V0**2 / (18 * mu * G) + 2 * V0 * seconds / 3, -(V0**2) / (18 * mu**2 * G)


def located_env(mu, adjoint=None):
    env = ll.make("RollingDisk", radius=RADIUS, gravity=G, dt=DT, floor=DiskFloor(static_friction=1.0, kinetic_friction=0.5))
    env = eqx.tree_at(lambda e: e.floor.kinetic_friction, env, mu)
    return env if adjoint is None else ll.with_adjoint(env, adjoint)


def launched():
    return jnp.array([0.0, RADIUS, 0.0, V0, 0.0, 0.0])


def located_position(mu, steps, adjoint=None):
    """x(T) of the located `RollingDisk`, its solver steps and whether every step succeeded."""
    env = located_env(mu, adjoint)

    def step(state, _):
        state, info = env.evolve(state, jnp.zeros(1))
        return state, (info["solver_steps"], info["solver_ok"])

    state, (taken, ok) = jax.lax.scan(step, ll.EnvState(y=launched(), steps=jnp.zeros((), int)), None, length=steps)
    return state.y[0], (jnp.sum(taken), jnp.all(ok))


def smooth_position(field, y0, steps):
    """x(T) of a smooth model `field(t, y, u)`, one Tsit5 solve per env step as a smooth scene steps."""
    integrator = ll.make_integrator("tsit5", max_steps=MAX_STEPS)

    def step(y, _):
        y, info = integrator.integrate(field, y, jnp.zeros(1), DT)
        return y, (info["solver_steps"], info["solver_ok"])

    y, (taken, ok) = jax.lax.scan(step, y0, None, length=steps)
    return y[0], (jnp.sum(taken), jnp.all(ok))


def tanh_position(mu, steps, epsilon):
    dynamics = located_env(mu).dynamics

    def field(t, y, u):
        force = -mu * dynamics.normal_force() * jnp.tanh(dynamics.slip_velocity(y) / epsilon)
        return dynamics.sliding_vector_field(t, y, u, force)

    return smooth_position(field, launched(), steps)


def penalty_position(mu, steps, epsilon):
    dynamics = located_env(mu).dynamics

    def field(t, y, u):
        sinking = dynamics.radius - y[1]
        # The floor pushes only where the disk sinks in, and never pulls.
        normal = jnp.where(sinking > 0, jnp.maximum(STIFFNESS * sinking - DAMPING * y[4], 0.0), 0.0)
        force = -mu * normal * jnp.tanh(dynamics.slip_velocity(y) / epsilon)
        free = dynamics.vector_field(t, y, u)
        zero = jnp.zeros_like(force)
        return free + jnp.stack([zero, zero, zero, force, normal, -dynamics.radius * force / dynamics.inertia])

    return smooth_position(field, launched(), steps)


def compiled(function, argument):
    """The program `jax.jit(function)` compiled for `argument`, and its compile time."""
    start = time.perf_counter()
    program = jax.jit(function).lower(argument).compile()
    return program, time.perf_counter() - start


def measure(name, position, mus, steps, forward_mode=False):
    """One model's row: accuracy against the closed form, steps, compile times, memory; and its
    two timed programs (forward, value and gradient)."""
    forward, forward_compile = compiled(jax.vmap(position), mus)
    if forward_mode:
        def value_and_slope(mu):
            (value, aux), (slope, _) = jax.jvp(position, (mu,), (jnp.ones_like(mu),))
            return (value, aux), slope
    else:
        value_and_slope = jax.value_and_grad(position, has_aux=True)
    gradient, gradient_compile = compiled(jax.vmap(value_and_slope), mus)
    first = {}
    start = time.perf_counter()
    jax.block_until_ready(forward(mus))
    first["forward"] = time.perf_counter() - start
    start = time.perf_counter()
    (value, (taken, ok)), slope = jax.block_until_ready(gradient(mus))
    first["gradient"] = time.perf_counter() - start
    expected, expected_slope = closed_form(np.asarray(mus), DT * steps)
    row = {
        "model": name,
        "envs": int(mus.shape[0]),
        "steps": steps,
        "position_error": float(np.max(np.abs(np.asarray(value) - expected))),
        "derivative_error": float(np.max(np.abs(np.asarray(slope) - expected_slope))),
        "derivative_finite_fraction": float(np.mean(np.isfinite(np.asarray(slope)))),
        "solver_steps_per_env": float(np.mean(np.asarray(taken))),
        "solver_ok_fraction": float(np.mean(np.asarray(ok))),
        "forward_compile_s": forward_compile,
        "gradient_compile_s": gradient_compile,
        "forward_temp_bytes": int(forward.memory_analysis().temp_size_in_bytes),
        "gradient_temp_bytes": int(gradient.memory_analysis().temp_size_in_bytes),
    }
    print(json.dumps(row), flush=True)
    programs = {
        f"{name} forward": lambda: jax.block_until_ready(forward(mus)),
        f"{name} gradient": lambda: jax.block_until_ready(gradient(mus)),
    }
    return row, programs, first


def from_reset(envs, steps, repeats):
    """Batch scale as an agent meets it: `envs` RollingDisks from `reset` (most slip, then roll)
    under the torque `sin(0.3 k)` of the largest action (beyond what static friction holds at
    its peaks, so some spin out), the value and gradient (reverse mode) of the summed final
    positions with respect to the shared `kinetic_friction`."""
    env = ll.make("RollingDisk")
    starts = jax.vmap(lambda key: env.reset(key=key)[0])(jax.random.split(jax.random.key(0), envs))
    actions = jnp.sin(0.3 * jnp.arange(steps))[:, None]

    def rollout(mu):
        moved = eqx.tree_at(lambda e: e.floor.kinetic_friction, env, mu)

        def one(state):
            def step(state, action):
                state, info = moved.evolve(state, moved.physical_input(action))
                return state, info["solver_ok"]

            state, ok = jax.lax.scan(step, state, actions)
            return state.y[0], jnp.all(ok)

        positions, ok = jax.vmap(one)(starts)
        return jnp.sum(positions), ok

    mu = jnp.asarray(0.4)
    forward, forward_compile = compiled(rollout, mu)
    gradient, gradient_compile = compiled(jax.value_and_grad(rollout, has_aux=True), mu)
    (_, ok), slope = jax.block_until_ready(gradient(mu))
    seconds = interleaved({"forward": lambda: jax.block_until_ready(forward(mu)),
                           "gradient": lambda: jax.block_until_ready(gradient(mu))}, repeats)
    row = {
        "workload": "RollingDisk from reset, torque sin(0.3 k)", "envs": envs, "steps": steps,
        "forward_s": float(np.median(seconds["forward"])), "value_and_grad_s": float(np.median(seconds["gradient"])),
        "forward_compile_s": forward_compile, "gradient_compile_s": gradient_compile,
        "gradient_temp_bytes": int(gradient.memory_analysis().temp_size_in_bytes),
        "solver_ok_fraction": float(np.mean(np.asarray(ok))), "gradient": float(slope),
    }
    row["gradient_over_forward"] = row["value_and_grad_s"] / row["forward_s"]
    print(json.dumps(row), flush=True)
    return row


def main(argv=None):
    arguments = sized_arguments(__doc__, argv, quick=(16, 20, 3), full=(256, 20, 5))
    out = output_folder(arguments)
    steps = arguments.steps
    if DT * steps <= V0 / (3 * MU_RANGE[0] * G):
        raise SystemExit(f"T = {DT * steps} s ends before every disk rolls; take more steps")
    mus = jnp.linspace(*MU_RANGE, arguments.envs)
    models = {
        "located": (lambda mu: located_position(mu, steps), False),
        "located, forward mode": (lambda mu: located_position(mu, steps, "forward"), True),
    }
    for epsilon in SHARPNESS:
        models[f"tanh {epsilon:g}"] = (lambda mu, epsilon=epsilon: tanh_position(mu, steps, epsilon), False)
    for epsilon in SHARPNESS:
        models[f"penalty {epsilon:g}"] = (lambda mu, epsilon=epsilon: penalty_position(mu, steps, epsilon), False)
    rows, programs, firsts = [], {}, {}
    for name, (position, forward_mode) in models.items():
        row, timed, first = measure(name, position, mus, steps, forward_mode)
        rows.append(row)
        firsts.update({f"{name} {kind}": seconds for kind, seconds in first.items()})
        # A call of over LONG seconds (the sharpest tanh's thousands of steps) is timed once, by
        # its first call after compiling: its spread is small beside its length.
        programs.update({key: thunk for key, thunk in timed.items() if firsts[key] < LONG})
    # Interleaved, so that the load of the shared machine falls on every model alike.
    seconds = interleaved(programs, arguments.repeats)
    for row in rows:
        for column, kind in (("forward_s", "forward"), ("value_and_grad_s", "gradient")):
            key = f"{row['model']} {kind}"
            row[column] = float(np.median(seconds[key])) if key in seconds else firsts[key]
            row[f"{kind}_repeats"] = len(seconds.get(key, [firsts[key]]))
        row["gradient_over_forward"] = row["value_and_grad_s"] / row["forward_s"]
    write_csv(out / "frictional_contact.csv", rows)
    scale = from_reset(arguments.envs, steps, arguments.repeats)
    write_csv(out / "frictional_contact_scale.csv", [scale])
    located = rows[0]
    ratios = {
        f"{row['model']} over located": {
            "forward": row["forward_s"] / located["forward_s"],
            "value_and_grad": row["value_and_grad_s"] / located["value_and_grad_s"],
        }
        for row in rows[1:]
    }
    write_record({"rows": rows, "ratios": ratios, "batch_scale": scale, "v0": V0, "radius": RADIUS, "gravity": G, "dt": DT,
                  "mu_range": MU_RANGE, "stiffness": STIFFNESS, "damping": DAMPING, "repeats": arguments.repeats,
                  "jax": jax.__version__, "backend": jax.default_backend()}, out / "frictional_contact.json")
    for row in rows:
        print(f"{row['model']:>22}: x(T) error {row['position_error']:.2e}, dx/dmu error {row['derivative_error']:.2e}, "
              f"{row['solver_steps_per_env']:.0f} steps, forward {row['forward_s'] * 1e3:.1f} ms, value and gradient "
              f"{row['value_and_grad_s'] * 1e3:.1f} ms ({row['gradient_over_forward']:.1f}x), gradient compile "
              f"{row['gradient_compile_s']:.1f} s, {row['gradient_temp_bytes'] / 2**20:.1f} MiB", flush=True)


if __name__ == "__main__":
    main()
