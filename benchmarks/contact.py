"""Located walls against penalty end stops: throughput (forward, value and gradient) and accuracy against SciPy.

A cart-pole (`CartPoleContinuous`, rail walls at `track_limit = 0.5` m) driven by random
forces into its walls, vmapped over N envs, T env steps of 0.02 s. Two contact models, both
with Tsit5 at rtol 1e-8, atol 1e-10:

- `located`: `restitution=1` walls, each impact located as an event and mapped
  (`lerax_like.hybrid`);
- `penalty`: `EndStops` at 1e6 N/m without damping (so elastic too), integrated through.

Throughput is env steps per second (N T over the median of `--repeats` runs after
compiling), of the rollout and of its value and gradient (with respect to the forces; on the
first 128 envs, as the penalty's gradient at N = 1024 does not fit in memory). The
accuracy is the largest state error of the first 16 envs over the whole rollout, against
SciPy's `solve_ivp` (DOP853, rtol = atol = 1e-13) with the walls as `events`, restarted at
each impact after the impulse map written out here (the cart's speed reversed; the pole's
rate from the conserved momentum conjugate to its angle). Also written: a bouncing ball's
trajectory through several impacts (event times marked) and its gradient by AD against
central finite differences across a restitution sweep.

    python -m benchmarks contact            # N = 1024, T = 30: results/contact*.csv, contact_*.png
    python -m benchmarks contact --quick    # N = 64, T = 20, into results/quick/
"""

import argparse
import csv
import json
import math
import pathlib
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

jax.config.update("jax_enable_x64", True)

import diffrax  # noqa: E402
import lerax_like as ll  # noqa: E402
from benchmarks import results_dir  # noqa: E402


TRACK = 0.5
RTOL, ATOL = 1e-8, 1e-10
CHECKED = 16  # envs checked against SciPy


def make_env(model: str):
    common = dict(
        track_limit=TRACK, x_threshold=jnp.inf, theta_threshold_radians=jnp.inf,
        solver="tsit5", stepsize_controller=diffrax.PIDController(rtol=RTOL, atol=ATOL),
    )
    if model == "located":
        # A located solve needs few steps per segment and the cart at most a few impacts per
        # env step; a reverse-mode gradient's memory grows with max_steps times the segments
        # (checkpoints), so both budgets are set to what the task needs (an exhausted one
        # would show in solver_ok_fraction).
        return ll.make("CartPoleContinuous", restitution=1.0, max_steps=64, max_events=4, **common)
    return ll.make("CartPoleContinuous", end_stop_stiffness=1e6, end_stop_damping=0.0, **common)


def rollout_batch(env, y0, actions):
    """States after each step, shape (N, T, 4), and whether every step succeeded."""

    def one(y, a):
        ys, info = ll.rollout(env, ll.EnvState(y=y, steps=jnp.zeros((), dtype=int)), a)
        return ys, jnp.all(info["solver_ok"]), jnp.sum(info.get("impacts", jnp.zeros(1, dtype=int)))

    return jax.vmap(one)(y0, actions)


def loss(env, y0, actions):
    ys, _, _ = rollout_batch(env, y0, actions)
    return jnp.sum(jnp.cos(ys[..., 2])) + jnp.sum(ys[..., 0] ** 2)


def _median_time(function, *args, repeats: int) -> float:
    jax.block_until_ready(function(*args))  # compile
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(function(*args))
        times.append(time.perf_counter() - start)
    return float(np.median(times))


# -- the SciPy reference ----------------------------------------------------------------


def _cartpole_field(p):
    gravity, cart_mass, pole_mass, half_length = p

    def field(t, y, force):
        _, x_dot, theta, theta_dot = y
        total = cart_mass + pole_mass
        temp = (force + pole_mass * half_length * theta_dot**2 * math.sin(theta)) / total
        theta_acc = (gravity * math.sin(theta) - math.cos(theta) * temp) / (
            half_length * (4.0 / 3.0 - pole_mass * math.cos(theta) ** 2 / total)
        )
        x_acc = temp - pole_mass * half_length * theta_acc * math.cos(theta) / total
        return [x_dot, x_acc, theta_dot, theta_acc]

    return field


def _wall_impact(y, p, e):
    """The cart's speed reversed times e; the pole's rate keeps p_theta = M21 x_dot + M22 theta_dot."""
    _, cart_mass, pole_mass, half_length = p
    x, x_dot, theta, theta_dot = y
    coupling = pole_mass * half_length * math.cos(theta)
    inertia = 4.0 / 3.0 * pole_mass * half_length**2
    new_x_dot = -e * x_dot
    new_theta_dot = theta_dot - coupling / inertia * (new_x_dot - x_dot)
    return np.array([x, new_x_dot, theta, new_theta_dot])


def scipy_reference(y0, forces, dt, p, e=1.0):
    """States after each step: DOP853 at 1e-13 between impacts, each wall located by `events`."""
    from scipy.integrate import solve_ivp

    field = _cartpole_field(p)
    left = lambda t, y, f: y[0] + TRACK  # noqa: E731
    right = lambda t, y, f: TRACK - y[0]  # noqa: E731
    left.terminal = right.terminal = True
    left.direction = right.direction = -1
    y, out = np.array(y0, dtype=float), []
    for force in forces:
        t = 0.0
        while t < dt:
            solution = solve_ivp(field, (t, dt), y, method="DOP853", rtol=1e-13, atol=1e-13,
                                 events=(left, right), args=(force,))
            y = solution.y[:, -1]
            if solution.status == 1:  # an event: impact, and go on from there
                t = float(solution.t[-1])
                y = _wall_impact(y, p, e)
            else:
                t = dt
        out.append(y.copy())
    return np.array(out)


# -- the two figures --------------------------------------------------------------------


def ball_trajectory(steps: int):
    env = ll.make("BouncingBall", restitution=0.8, dt=0.01)
    step = jax.jit(lambda state, u: env.evolve(state, u))
    state = ll.EnvState(y=jnp.array([-0.5, 1.5, 1.5, 0.0]), steps=jnp.zeros((), dtype=int))
    u = jnp.array([2.0, 0.0])
    ts, ys, impacts = [0.0], [np.asarray(state.y)], []
    for k in range(steps):
        state, info = step(state, u)
        if int(info["impacts"]):
            impacts.append(k * 0.01 + float(info["first_impact_time"]))
        ts.append((k + 1) * 0.01)
        ys.append(np.asarray(state.y))
    return np.array(ts), np.array(ys), impacts


def restitution_sweep(values):
    """d loss / d e and d loss / d h (initial height) of a 50-step ball rollout: AD and central FD."""
    env = ll.make("BouncingBall", restitution=0.8)
    actions = jnp.tile(jnp.array([0.3, 0.0]), (50, 1))

    def loss_of(theta):
        e = eqx.tree_at(lambda e: e.contacts[0].restitution, env, theta[0])
        state = ll.EnvState(y=jnp.array([0.5, theta[1], 1.0, 0.0]), steps=jnp.zeros((), dtype=int))
        ys, info = ll.rollout(e, state, actions)
        return jnp.sum(ys[:, :2] ** 2) + 0.1 * jnp.sum(ys[:, 2:] ** 2), jnp.sum(info["impacts"])

    value_and_grad = jax.jit(jax.vmap(jax.value_and_grad(loss_of, has_aux=True)))
    rows = []
    for e in values:
        theta = jnp.array([e, 1.0])
        h = 1e-6
        points = jnp.stack([theta, theta.at[0].add(h), theta.at[0].add(-h), theta.at[1].add(h), theta.at[1].add(-h)])
        (losses, impacts), grads = value_and_grad(points)
        fd = [(losses[1] - losses[2]) / (2 * h), (losses[3] - losses[4]) / (2 * h)]
        for i, name in enumerate(["restitution", "initial_height"]):
            ad = float(grads[0, i])
            rows.append({"restitution": float(e), "wrt": name, "ad": ad, "fd": float(fd[i]),
                         "relative_error": abs(ad - float(fd[i])) / abs(float(fd[i])), "impacts": int(impacts[0])})
    return rows


def plot(out: pathlib.Path, trajectory, sweep):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ts, ys, impacts = trajectory
    figure, axis = plt.subplots(figsize=(7, 3.5))
    axis.plot(ts, ys[:, 1], label="height z (m)")
    axis.plot(ts, ys[:, 0], label="x (m); wall at 1 m")
    for i, t in enumerate(impacts):
        axis.axvline(t, color="grey", linewidth=0.6, linestyle=":", label="located impact" if i == 0 else None)
    axis.set_xlabel("time (s)")
    axis.set_title("BouncingBall (e = 0.8, thrust 2 N towards the wall): impacts located as events")
    axis.legend(loc="upper right", fontsize=8)
    figure.tight_layout()
    figure.savefig(out / "contact_trajectory.png", dpi=120)
    plt.close(figure)

    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for name, marker in (("restitution", "o"), ("initial_height", "s")):
        rows = [r for r in sweep if r["wrt"] == name]
        e = [r["restitution"] for r in rows]
        top.plot(e, [r["ad"] for r in rows], marker=marker, label=f"AD, d loss / d {name}")
        top.plot(e, [r["fd"] for r in rows], marker="x", linestyle="none", color="black",
                 label="central FD" if name == "restitution" else None)
        bottom.semilogy(e, [max(r["relative_error"], 1e-17) for r in rows], marker=marker, label=name)
    top.set_ylabel("gradient")
    top.legend(fontsize=8)
    top.set_title("50-step BouncingBall rollout through its impacts: AD against FD (float64)")
    bottom.set_ylabel("|AD - FD| / |FD|")
    bottom.set_xlabel("restitution e")
    bottom.legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(out / "contact_gradients.png", dpi=120)
    plt.close(figure)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    parser.add_argument("--envs", type=int, default=None)
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--gradient-envs", type=int, default=None,
                        help="envs of the value-and-gradient timing (default 128; 16 with --quick)")
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    envs = args.envs or (64 if args.quick else 1024)
    steps = args.steps or (20 if args.quick else 30)
    gradient_envs = min(envs, args.gradient_envs or (16 if args.quick else 128))

    key_start, key_force = jr.split(jr.key(0))
    y0 = jr.uniform(key_start, (envs, 4), minval=-0.05, maxval=0.05)
    # Forces that change sign every 25 steps (0.5 s): the cart is driven into both walls.
    phase = jr.uniform(key_force, (envs, 1), maxval=2 * math.pi)
    actions = jnp.sin(phase + jnp.arange(steps)[None, :] * 2 * math.pi / 50)[..., None]

    rows = []
    for model in ("located", "penalty"):
        env = make_env(model)
        forward = jax.jit(lambda y0, a, env=env: rollout_batch(env, y0, a))
        ys, ok, impacts = forward(y0, actions)
        forward_time = _median_time(forward, y0, actions, repeats=args.repeats)
        # The penalty's gradient keeps max_steps (4096) checkpoints per step and env: at N = 1024
        # it does not fit in memory, so both gradients are timed on the first gradient_envs.
        gradient = jax.jit(jax.value_and_grad(lambda a, env=env: loss(env, y0[:gradient_envs], a)))
        gradient_time = _median_time(gradient, actions[:gradient_envs], repeats=args.repeats)
        p = tuple(float(v) for v in (env.dynamics.gravity, env.dynamics.cart_mass, env.dynamics.pole_mass,
                                     env.dynamics.half_length))
        errors, penetration = [], float(jnp.max(jnp.abs(ys[..., 0])) - TRACK)
        for i in range(min(CHECKED, envs)):
            forces = np.asarray(env.force_mag * np.clip(np.asarray(actions[i, :, 0]), -1, 1))
            reference = scipy_reference(np.asarray(y0[i]), forces, float(env.dt), p)
            errors.append(float(np.max(np.abs(np.asarray(ys[i]) - reference))))
        row = {
            "model": model, "envs": envs, "steps": steps,
            "forward_steps_per_s": envs * steps / forward_time,
            "gradient_envs": gradient_envs,
            "value_and_grad_steps_per_s": gradient_envs * steps / gradient_time,
            "max_error": max(errors), "median_error": float(np.median(errors)),
            "max_penetration_m": max(penetration, 0.0),
            "solver_ok_fraction": float(jnp.mean(ok)), "mean_impacts": float(jnp.mean(impacts)),
        }
        print(json.dumps(row), flush=True)
        rows.append(row)
    with open(out / "contact.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    located, penalty = rows
    ratios = {
        "forward_ratio": located["forward_steps_per_s"] / penalty["forward_steps_per_s"],
        "value_and_grad_ratio": located["value_and_grad_steps_per_s"] / penalty["value_and_grad_steps_per_s"],
        "error_ratio": located["max_error"] / penalty["max_error"],
    }
    print(json.dumps(ratios), flush=True)

    sweep = restitution_sweep(np.linspace(0.1, 1.0, 4 if args.quick else 7))
    with open(out / "contact_sweep.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(sweep[0]))
        writer.writeheader()
        writer.writerows(sweep)
    print("largest AD/FD relative error in the sweep:", max(r["relative_error"] for r in sweep), flush=True)
    trajectory = ball_trajectory(150)
    try:
        plot(out, trajectory, sweep)
    except ImportError:
        print("figures skipped: pip install matplotlib")


if __name__ == "__main__":
    main()
