"""Cost of a batched gradient through `ll.rollout`, beside a hand-written pure-JAX floor of the same arithmetic.

N envs from distinct resets (`jax.vmap`), T env steps of a constant action, loss the mean of
the squared states. Per row: the forward pass, `jax.value_and_grad` (reverse mode) and
`jax.jacfwd` (forward mode, `ll.with_adjoint(env, "forward")`) with respect to the scene's
`gravity`, the min of `--repeats` runs after compiling; XLA's temporary memory of the compiled
gradient (`memory_analysis().temp_size_in_bytes`) and its compile time.

The floor is the least any JAX code must do for the same numbers: the scene's own vector field
(`env.physics.vector_field`) and physical input, the same solver's steps written out in a
`lax.scan` (an explicit method's Butcher tableau, stage by stage; an implicit method's diffrax
`step`), as many equal steps per env step as ours took on average (`info["solver_steps"]`,
rounded up), no checks, no info. For a contact scene each of those steps also locates the
impact when a gap changes sign: four Newton steps on the cubic Hermite interpolant of the
step, the contact's own impact map, and a second step over the rest of the interval (both
branches computed, as `vmap` would). No failure handling, no rest, at most one impact per step:
a floor, not a substitute.

Peer: gymnax's Pendulum on the Pendulum row. gymnax 0.0.9 (installed) has no
`with_transition_gradients`: its `step` returns the state under `lax.stop_gradient`, so its
gradient through the dynamics is zero (recorded), and its times are a forward reference only.

Goals (issue 29): reverse at most 2x the floor's for fixed-step smooth rows, 3x for adaptive
and contact rows; at most 15x the row's own forward pass; temp memory under 1 GiB at N = 1024;
compile of the gradient under 30 s.

    python -m benchmarks gradient_cost            # N = 1024, T = 100, 3 repeats: results/gradient_cost.csv
    python -m benchmarks gradient_cost --quick    # N = 16, T = 20, 2 repeats, into results/quick/
"""

import dataclasses
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import lerax_like as ll  # noqa: E402
from benchmarks import output_folder, sized_arguments  # noqa: E402
from benchmarks._workload import compile_seconds, time_once  # noqa: E402
from lerax_like.analysis.recording import write_csv  # noqa: E402
from lerax_like.integrate import SOLVERS  # noqa: E402

GIB = 2**30
ACTION = 0.3


@dataclasses.dataclass(frozen=True)
class Row:
    name: str
    make: Callable[[], ll.AbstractEnv]
    solver: str
    kind: str  # "fixed", "adaptive" or "contact": which floor goal applies


def _cart_pole(**options):
    return lambda: ll.make("CartPoleContinuous", **options)


ROWS = (
    Row("CartPoleContinuous", _cart_pole(), "euler", "fixed"),
    Row("CartPoleContinuous", _cart_pole(solver="rk4"), "rk4", "fixed"),
    Row("CartPoleContinuous", _cart_pole(solver="tsit5"), "tsit5", "adaptive"),
    Row("CartPoleContinuous, joint_damping=300", _cart_pole(solver="kvaerno5", joint_damping=300.0), "kvaerno5",
        "adaptive"),
    Row("CartPoleContinuous, walls", _cart_pole(solver="tsit5", restitution=0.8), "tsit5", "contact"),
    Row("CartPoleContinuous, walls", _cart_pole(solver="rk4", restitution=0.8), "rk4", "contact"),
    Row("BouncingBall", ll.BouncingBall, "tsit5", "contact"),
    Row("RimlessWheel", ll.RimlessWheel, "tsit5", "contact"),
    Row("DoubleCartPole", ll.DoubleCartPole, "rk4", "fixed"),
    Row("Pendulum", ll.Pendulum, "semi_implicit_euler", "fixed"),
)
GOAL_OVER_FLOOR = {"fixed": 2.0, "adaptive": 3.0, "contact": 3.0}
GOAL_OVER_FORWARD = 15.0


def _with_gravity(env, gravity):
    return eqx.tree_at(lambda e: e.dynamics.gravity, env, gravity)


def _loss(ys):
    return jnp.mean(ys**2)


# --- ours -----------------------------------------------------------------------------------


def ours(env, states, actions):
    """`batch_loss(gravity)` of `ll.rollout`, vmapped over the start states."""

    def one(gravity, state):
        ys, _ = ll.rollout(_with_gravity(env, gravity), state, actions)
        return _loss(ys)

    return lambda gravity: jnp.mean(jax.vmap(one, in_axes=(None, 0))(gravity, states))


def mean_solver_steps(env, states, actions) -> float:
    """Solver steps of one env step, averaged over envs and steps, as ours took them."""
    infos = jax.jit(jax.vmap(lambda s: ll.rollout(env, s, actions)[1]))(states)
    return float(jnp.mean(infos["solver_steps"]))


# --- the floor ------------------------------------------------------------------------------


def _explicit_step(tableau: diffrax.ButcherTableau, f, y, h):
    stages = [f(y)]
    for a_row in tableau.a_lower:
        stages.append(f(y + h * sum(float(a) * k for a, k in zip(a_row, stages) if a != 0)))
    return y + h * sum(float(b) * k for b, k in zip(tableau.b_sol, stages) if b != 0)


def _solver_step(solver_name: str, field, u):
    """`step(y, h)` of the preset's method on `dy/dt = field(y, u)`, written out where it is explicit."""
    f = lambda y: field(0.0, y, u)  # noqa: E731 (autonomous within a step: the input is held)
    if solver_name == "euler":
        return lambda y, h: y + h * f(y)
    preset = SOLVERS.find(solver_name)
    solver = (preset.make_fixed_step_solver or preset.make_solver)()
    tableau = getattr(solver, "tableau", None)
    if isinstance(solver, diffrax.AbstractERK) and isinstance(tableau, diffrax.ButcherTableau):
        return lambda y, h: _explicit_step(tableau, f, y, h)
    term = diffrax.ODETerm(lambda t, y, args: field(t, y, args))

    def step(y, h):
        t0 = jnp.zeros((), y.dtype)
        state = solver.init(term, t0, t0 + h, y, u)
        return solver.step(term, t0, t0 + h, y, u, state, made_jump=False)[0]

    return step


def _pendulum_step(gravity, y, torque, dt):
    """Gymnasium's Pendulum step (semi-implicit Euler, speed clipped), as `benchmarks/_floors.py` has it."""
    max_speed, mass, length = 8.0, 1.0, 1.0
    speed = y[1] + (3 * gravity / (2 * length) * jnp.sin(y[0]) + 3.0 / (mass * length**2) * torque) * dt
    speed = jnp.clip(speed, -max_speed, max_speed)
    return jnp.stack([y[0] + speed * dt, speed])


def _impact_step(env, step, y, u, h):
    """One solver step, and where a gap changes sign over it: the impact located and mapped, then the rest."""
    contact = env.contacts[0]
    y1 = step(y, h)
    g0, g1 = contact.gaps(env.dynamics, y), contact.gaps(env.dynamics, y1)
    surface = jnp.argmin(g1)
    crossed = g1[surface] < 0
    f0, f1 = env.physics.vector_field(0.0, y, u), env.physics.vector_field(0.0, y1, u)

    def state_at(s):  # the cubic Hermite interpolant of the step
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * y + h10 * h * f0 + h01 * y1 + h11 * h * f1

    gap = lambda s: contact.gaps(env.dynamics, state_at(s))[surface]  # noqa: E731
    s = jnp.clip(g0[surface] / jnp.where(crossed, g0[surface] - g1[surface], 1.0), 0.0, 1.0)
    for _ in range(4):
        value, slope = jax.jvp(gap, (s,), (jnp.ones_like(s),))
        s = jnp.clip(s - value / jnp.where(slope == 0, 1.0, slope), 0.0, 1.0)
    hit = state_at(s)
    after = hit
    for index in range(g1.shape[0]):
        after = jnp.where(surface == index, contact.impact(env.dynamics, hit, index), after)
    return jnp.where(crossed, step(after, (1 - s) * h), y1)


def floor(row: Row, env, states, actions, steps_per_env_step: int):
    """`batch_loss(gravity)` of the hand-written floor (module docstring)."""
    dt = env.dt
    h = dt / steps_per_env_step

    def one(gravity, y0):
        scene = _with_gravity(env, gravity)

        def body(y, action):
            u = scene.physical_input(action)
            if row.name == "Pendulum":
                y = _pendulum_step(gravity, y, u[0], dt)
                return y, y
            step = _solver_step(row.solver, scene.physics.vector_field, u)
            for _ in range(steps_per_env_step):
                y = _impact_step(scene, step, y, u, h) if row.kind == "contact" else step(y, h)
            return y, y

        _, ys = jax.lax.scan(body, y0, actions)
        return _loss(ys)

    return lambda gravity: jnp.mean(jax.vmap(one, in_axes=(None, 0))(gravity, states))


def gymnax_pendulum(states, actions):
    """`batch_loss(g)` of gymnax's Pendulum-v1 from the same starts (its step stops gradients)."""
    from gymnax.environments.classic_control.pendulum import EnvState, Pendulum

    env = Pendulum()

    def one(gravity, y0):
        params = env.default_params.replace(g=gravity)
        state = EnvState(theta=y0[0], theta_dot=y0[1], last_u=jnp.zeros(()), time=0)

        def body(state, action):
            _, state, *_ = env.step_env(jr.key(0), state, action, params)
            y = jnp.stack([state.theta, state.theta_dot])
            return state, y

        _, ys = jax.lax.scan(body, state, actions)  # both take the torque (N m) as the action
        return _loss(ys)

    return lambda gravity: jnp.mean(jax.vmap(one, in_axes=(None, 0))(gravity, states))


# --- measuring ------------------------------------------------------------------------------


def _compiled(function, argument):
    seconds, compiled = compile_seconds(jax.jit(function), argument)
    return compiled, seconds


def _best(compiled, argument, repeats: int) -> float:
    time_once(compiled, argument)  # the first call after compiling is not timed
    return min(time_once(compiled, argument) for _ in range(repeats))


def measure(batch_loss, gravity, repeats: int, *, forward_mode_loss=None) -> dict:
    """Forward, reverse and forward-mode times, the gradient's temp memory and compile time."""
    forward, forward_compile = _compiled(batch_loss, gravity)
    reverse, reverse_compile = _compiled(jax.value_and_grad(batch_loss), gravity)
    result = {
        "forward_s": _best(forward, gravity, repeats),
        "reverse_s": _best(reverse, gravity, repeats),
        "reverse_temp_bytes": reverse.memory_analysis().temp_size_in_bytes,
        "forward_compile_s": forward_compile,
        "reverse_compile_s": reverse_compile,
        "gradient": float(reverse(gravity)[1]),
    }
    if forward_mode_loss is not None:
        try:
            tangent, tangent_compile = _compiled(jax.jacfwd(forward_mode_loss), gravity)
            result |= {"jacfwd_s": _best(tangent, gravity, repeats), "jacfwd_compile_s": tangent_compile,
                       "jacfwd_gradient": float(tangent(gravity))}
        except Exception as error:  # recorded, not hidden: forward mode is part A of issue 29
            result["jacfwd_error"] = f"{type(error).__name__}: {str(error).splitlines()[0][:160]}"
    return result


def run_row(row: Row, num_envs: int, num_steps: int, repeats: int) -> dict:
    env = row.make()
    states = jax.vmap(lambda key: env.reset(key=key)[0])(jr.split(jr.key(0), num_envs))
    actions = jnp.full((num_steps, *env.action_space.shape), ACTION, env.dt.dtype)
    gravity = jnp.asarray(env.dynamics.gravity)
    steps = mean_solver_steps(env, states, actions)
    record = {"scene": row.name, "solver": row.solver, "kind": row.kind, "envs": num_envs, "steps": num_steps,
              "solver_steps_per_env_step": steps}
    forward_env = ll.with_adjoint(env, "forward")
    ours_result = measure(ours(env, states, actions), gravity, repeats,
                          forward_mode_loss=ours(forward_env, states, actions))
    floor_steps = max(1, math.ceil(steps - 1e-9))
    floor_result = measure(floor(row, env, states.y, actions, floor_steps), gravity, repeats)
    record |= ours_result | {f"floor_{name}": value for name, value in floor_result.items()}
    record["floor_solver_steps"] = floor_steps
    if row.name == "Pendulum":
        try:
            peer = measure(gymnax_pendulum(states.y, actions), gravity, repeats)
            record |= {f"gymnax_{name}": value for name, value in peer.items()}
        except ImportError as error:
            record["gymnax_error"] = str(error)
    record["reverse_over_floor"] = record["reverse_s"] / record["floor_reverse_s"]
    record["reverse_over_forward"] = record["reverse_s"] / record["forward_s"]
    record["floor_reverse_over_forward"] = record["floor_reverse_s"] / record["floor_forward_s"]
    record["forward_over_floor"] = record["forward_s"] / record["floor_forward_s"]
    record["goal_over_floor"] = GOAL_OVER_FLOOR[row.kind]
    record["meets_goals"] = bool(
        record["reverse_over_floor"] <= record["goal_over_floor"]
        and record["reverse_over_forward"] <= GOAL_OVER_FORWARD
        and record["reverse_temp_bytes"] < GIB * num_envs / 1024
        and record["reverse_compile_s"] < 30
    )
    return record


COLUMNS = (
    "scene", "solver", "kind", "envs", "steps", "solver_steps_per_env_step", "floor_solver_steps",
    "forward_s", "reverse_s", "jacfwd_s", "reverse_temp_bytes", "forward_compile_s", "reverse_compile_s",
    "jacfwd_compile_s", "floor_forward_s", "floor_reverse_s", "floor_reverse_temp_bytes", "floor_reverse_compile_s",
    "reverse_over_floor", "reverse_over_forward", "floor_reverse_over_forward", "forward_over_floor",
    "goal_over_floor", "meets_goals", "gradient", "jacfwd_gradient", "floor_gradient", "jacfwd_error",
    "gymnax_forward_s", "gymnax_reverse_s", "gymnax_gradient", "gymnax_error", "error",
)


def main(argv=None):
    arguments = sized_arguments(__doc__.splitlines()[0], argv, quick=(16, 20, 2), full=(1024, 100, 3))
    out = output_folder(arguments)
    rows = []
    for row in ROWS:
        try:
            record = run_row(row, arguments.envs, arguments.steps, arguments.repeats)
        except Exception as error:  # one row's failure (out of memory) is recorded, the others still run
            record = {"scene": row.name, "solver": row.solver, "kind": row.kind, "envs": arguments.envs,
                      "steps": arguments.steps, "error": f"{type(error).__name__}: {str(error).splitlines()[0][:200]}"}
        rows.append(record)
        print(", ".join(f"{key}={record[key]:.4g}" if isinstance(record[key], float) else f"{key}={record[key]}"
                        for key in COLUMNS if key in record), flush=True)
        write_csv(rows, out / "gradient_cost.csv", columns=COLUMNS)


if __name__ == "__main__":
    main()
