"""The passive rimless wheel's limit cycle: its post-impact speed from the env's own located impacts, to 1e-9.

`RimlessWheel` with zero torque (default parameters: 8 spokes, alpha = pi/8, slope 0.08 rad,
l = 1 m, g = 9.81, Tedrake's and Drake's), stepped by the env itself (`lerax_like.hybrid`
locating every heel strike, Dopri8 at rtol = atol = 1e-12), from a grid of starts that pass
over the top: three stance angles, five speeds. Within a step that holds one heel strike, the
speed just after it follows from the step's end state by the stance's energy (conserved
between impacts with zero torque):
`theta_dot+ = sqrt(theta_dot**2 + 2 (g / l) (cos(theta) - cos(slope - alpha)))`.
The last one of each start is compared with the closed form
`cot(2 alpha) sqrt(4 (g / l) sin(alpha) sin(slope))` and with SciPy (`solve_ivp` DOP853 with
located events, restarted at each impact, 1e-13), and the approach to the cycle with the
step map's contraction `cos(2 alpha)**2`. The figure is a phase portrait with the impacts.

    python -m benchmarks rimless_wheel            # writes results/rimless_wheel.json and .png
    python -m benchmarks rimless_wheel --quick    # 400 steps, into results/quick/
"""

import argparse
import json
import pathlib
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402  (after float64 is on)
from benchmarks import results_dir  # noqa: E402
from lerax_like.analysis.hybrid_reference import Contact, hybrid_reference  # noqa: E402


def make_env(dt: float = 0.05):
    controller = diffrax.PIDController(rtol=1e-12, atol=1e-12)
    return ll.make("RimlessWheel", solver="dopri8", stepsize_controller=controller, max_steps=100_000, dt=dt)


def passive_run(env, starts, steps: int):
    """End states and impact counts of every env step from each start, zero torque (vmapped)."""

    @eqx.filter_jit
    def run(env, y0):
        def body(state, _):
            state, info = env.evolve(state, jnp.zeros(1))
            return state, (state.y, info["impacts"], info["solver_ok"])

        return jax.lax.scan(body, ll.EnvState(y=y0, steps=jnp.asarray(0)), None, length=steps)[1]

    return jax.vmap(run, in_axes=(None, 0))(env, starts)


def speed_after_impact(dynamics, y):
    """The post-impact speed of the stance a state belongs to, by the stance's energy."""
    theta, theta_dot = y[..., 0], y[..., 1]
    g_over_l = float(dynamics.gravity / dynamics.leg_length)
    start = float(dynamics.slope - dynamics.spoke_half_angle)
    return np.sqrt(theta_dot**2 + 2 * g_over_l * (np.cos(theta) - np.cos(start)))


def speed_before_impact(dynamics, y):
    theta, theta_dot = y[..., 0], y[..., 1]
    g_over_l = float(dynamics.gravity / dynamics.leg_length)
    end = float(dynamics.slope + dynamics.spoke_half_angle)
    return np.sqrt(theta_dot**2 + 2 * g_over_l * (np.cos(theta) - np.cos(end)))


def scipy_cycle(dynamics, start, seconds: float) -> list[float]:
    contacts = [Contact(dynamics.front_gap, dynamics.heel_strike), Contact(dynamics.rear_gap, dynamics.rear_strike)]
    solution = hybrid_reference(dynamics.vector_field, contacts, start, np.zeros(1), seconds, rtol=1e-13, atol=1e-13)
    return [float(segment.y[1, 0]) for segment in solution.segments[1:]]


def phase_portrait(env, starts, path: pathlib.Path, steps: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dynamics = env.dynamics
    ys, impacts, _ = (np.asarray(a) for a in passive_run(env, jnp.asarray(starts), steps))
    alpha, slope = float(dynamics.spoke_half_angle), float(dynamics.slope)
    figure, axes = plt.subplots(figsize=(7, 4.5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for index, start in enumerate(starts):
        path_y = np.concatenate([start[None], ys[index]])
        colour = colours[index % len(colours)]
        segment = [path_y[0]]
        for k in range(steps):
            before, after = path_y[k], path_y[k + 1]
            if impacts[index, k] == 0:
                segment.append(after)
                continue
            # The stance closes at the heel strike; the next opens just after it.
            pre = np.array([slope + alpha, speed_before_impact(dynamics, before)])
            post = np.array([slope - alpha, speed_after_impact(dynamics, after)])
            segment.append(pre)
            axes.plot(*np.array(segment).T, color=colour, lw=1)
            axes.plot(*np.array([pre, post]).T, color=colour, lw=0.8, ls=":")
            axes.plot(*pre, "v", color=colour, ms=4)
            axes.plot(*post, "^", color=colour, ms=4)
            segment = [post, after]
        axes.plot(*np.array(segment).T, color=colour, lw=1, label=f"start ({start[0]:.2f}, {start[1]:.2f})")
    # The limit cycle's stance, from the closed form's post-impact speed, by energy.
    omega = float(dynamics.limit_cycle_speed)
    theta = np.linspace(slope - alpha, slope + alpha, 200)
    g_over_l = float(dynamics.gravity / dynamics.leg_length)
    cycle = np.sqrt(omega**2 + 2 * g_over_l * (np.cos(slope - alpha) - np.cos(theta)))
    axes.plot(theta, cycle, color="black", lw=1.5, ls="--", zorder=5, label=f"limit cycle (closed form, {omega:.6f} rad/s after impact)")
    axes.set_xlabel("theta (rad, stance spoke from vertical, + downhill)")
    axes.set_ylabel("theta_dot (rad/s)")
    axes.set_title("Passive rimless wheel: heel strikes (v before, ^ after) onto the limit cycle")
    axes.legend(fontsize=7, loc="upper left")
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    plt.close(figure)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    parser.add_argument("--steps", type=int, default=None, help="env steps of 0.05 s (default 1600, 80 s)")
    args = parser.parse_args(argv)
    out = args.out or results_dir(args.quick)
    out.mkdir(parents=True, exist_ok=True)
    steps = args.steps or (400 if args.quick else 1600)

    env = make_env()
    dynamics = env.dynamics
    closed_form = float(dynamics.limit_cycle_speed)
    over = float(dynamics.speed_to_pass_the_top)
    after_strike = float(dynamics.slope - dynamics.spoke_half_angle)
    # Three stance angles (just after a strike, over the foot, near the next strike) and
    # five speeds, each start with the energy to pass over the top.
    starts = [[theta, factor * over] for theta in (after_strike, 0.0, 0.3) for factor in (1.02, 1.5, 2.0, 3.0, 4.0)]
    starts = np.array(starts)

    started = time.perf_counter()
    ys, impacts, ok = (np.asarray(a) for a in passive_run(env, jnp.asarray(starts), steps))
    seconds = time.perf_counter() - started
    if not ok.all():
        raise RuntimeError("a passive step failed (solver_ok False)")
    per_start = []
    for index, start in enumerate(starts):
        single = np.flatnonzero(impacts[index] == 1)
        speeds = speed_after_impact(dynamics, ys[index, single])
        distances = np.abs(speeds - closed_form)
        usable = distances > 1e-7  # the contraction is read where rounding does not dominate
        ratios = distances[1:][usable[1:] & usable[:-1]] / distances[:-1][usable[1:] & usable[:-1]]
        per_start.append({
            "start": start.tolist(),
            "impacts": int(impacts[index].sum()),
            "steps_with_two_impacts": int((impacts[index] > 1).sum()),
            "rolled_back": bool(np.any(ys[index, :, 1] < 0)),
            "post_impact_speed_last": float(speeds[-1]),
            "error_last": float(speeds[-1] - closed_form),
            "first_speeds": speeds[:6].tolist(),
            "median_contraction": float(np.median(ratios)) if len(ratios) else None,
        })
    last = np.array([entry["post_impact_speed_last"] for entry in per_start])
    reference = scipy_cycle(dynamics, np.array([after_strike, 2.0]), steps * float(env.dt))
    result = {
        "parameters": {name: float(getattr(dynamics, name)) for name in ("leg_length", "spoke_half_angle", "slope", "gravity", "mass")},
        "solver": "dopri8, PIDController(rtol=1e-12, atol=1e-12), dt=0.05",
        "env_steps": steps,
        "closed_form_post_impact_speed": closed_form,
        "speed_to_pass_the_top": over,
        "contraction_closed_form": float(np.cos(2 * dynamics.spoke_half_angle) ** 2),
        "env_post_impact_speed": float(np.median(last)),
        "env_max_abs_error": float(np.max(np.abs(last - closed_form))),
        "env_spread_over_starts": float(np.max(last) - np.min(last)),
        "scipy_post_impact_speed": reference[-1],
        "scipy_abs_error": abs(reference[-1] - closed_form),
        "starts": per_start,
        "run_seconds_including_compile": seconds,
    }
    (out / "rimless_wheel.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"closed form  theta_dot+ = {closed_form:.12f} rad/s")
    print(f"env (15 starts, last impact) {result['env_post_impact_speed']:.12f}, max |error| {result['env_max_abs_error']:.2e}")
    print(f"scipy        theta_dot+ = {reference[-1]:.12f}, |error| {result['scipy_abs_error']:.2e}")
    contractions = [entry["median_contraction"] for entry in per_start if entry["median_contraction"] is not None]
    print(f"contraction per step: median {np.median(contractions):.6f} (closed form {result['contraction_closed_form']:.6f})")
    try:
        phase_portrait(make_env(dt=0.01), np.array([[after_strike, 1.02 * over], [after_strike, 4.0 * over], [0.3, 3.0]]),
                       out / "rimless_wheel.png", 500 if not args.quick else 200)
    except ImportError:
        print("no matplotlib: no figure")


if __name__ == "__main__":
    main()
