"""Passive walkers' gaits against slope, from the simulator's own derivatives.

The simplest walker (Garcia, Chatterjee, Ruina and Coleman 1998): its long-period (stable)
and short-period (unstable) period-one gaits continued in the slope gamma, from near 0 to
past the long-period gait's first period doubling, each point a Newton solve of the return
map (`lerax_like.analysis.gait`), the next point predicted by the implicit-function
derivative dy*/dgamma; the period doubling located where the largest eigenvalue's modulus
reaches 1 by Newton on gamma with d|lambda|/dgamma. The compass gait (Goswami, Thuilot and
Espiau 1996) at its nominal parameters: the gait, its eigenvalues, its limit cycle in the
phase plane, and the slope of its first period doubling, found the same way.

    python -m benchmarks walkers            # writes results/walkers.json and two PNGs
    python -m benchmarks walkers --quick    # fewer slopes, into results/quick/
"""

import json
import time

import diffrax
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

from benchmarks import benchmark_parser, output_folder  # noqa: E402
from lerax_like.analysis.gait import find_gait, gait_sensitivity  # noqa: E402
from lerax_like.physics.compass_gait import CompassGaitDynamics  # noqa: E402
from lerax_like.physics.simplest_walker import SimplestWalkerDynamics  # noqa: E402


def _record(gamma, gait):
    return {
        "slope": gamma, "fixed_point": gait.fixed_point.tolist(), "period": gait.period,
        "eigenvalues": [[value.real, value.imag] for value in gait.eigenvalues],
        "spectral_radius": float(np.max(np.abs(gait.eigenvalues))), "converged": gait.converged,
    }


def continue_in_slope(make, gait, slopes):
    """Gaits along `slopes` (ordered away from the first gait's), each Newton start predicted by dy*/dslope
    (the implicit-function derivative of the previous gait)."""
    points, previous = [], None
    for gamma in slopes:
        if previous is not None:
            # First order in log-log (exact for the small-slope law y* ~ gamma^(1/3)):
            # y = y0 (gamma / gamma0)^p with p = gamma0 y0' / y0, where y0 has no zero entry.
            slope, derivative = previous
            y0 = gait.fixed_point
            exponent = slope * derivative / np.where(y0 == 0, 1.0, y0)
            guess = np.where(y0 == 0, y0 + derivative * (gamma - slope), y0 * (gamma / slope) ** exponent)
        else:
            guess = gait.fixed_point
        dynamics = make(gamma)
        gait = find_gait(dynamics, jnp.asarray(guess))
        if not gait.converged:
            print(f"  slope {gamma:.6g}: Newton did not converge; the branch stops here")
            break
        points.append(_record(gamma, gait))
        previous = (gamma, gait_sensitivity(dynamics, gait, ["slope"]).fixed_point["slope"])
    return points


def period_doubling(make, gamma, guess, step=1e-3, iterations=40):
    """The slope where the largest eigenvalue's modulus reaches 1, from a stable `gamma` upwards.

    Bracketed first (slopes `step` apart, each start predicted by dy*/dslope), then
    Newton on the slope with d|lambda|/dslope, kept inside the bracket by bisection: the
    modulus is not smooth where a complex pair turns real, so plain Newton can leave.
    """
    low, high, gaits = gamma, None, {}

    def solve(slope, start):
        dynamics = make(slope)
        gait = find_gait(dynamics, jnp.asarray(start))
        sensitivity = gait_sensitivity(dynamics, gait, ["slope"])
        gaits[slope] = (gait, sensitivity)
        return gait, sensitivity

    gait, sensitivity = solve(low, guess)
    while high is None:
        trial = low + step
        other, other_sensitivity = solve(trial, gait.fixed_point + sensitivity.fixed_point["slope"] * step)
        if not other.converged:
            step /= 2
            continue
        if np.max(np.abs(other.eigenvalues)) >= 1:
            high = trial
        else:
            low, gait, sensitivity = trial, other, other_sensitivity
    slope = high
    for _ in range(iterations):
        gait, sensitivity = gaits[slope] if slope in gaits else solve(slope, gait.fixed_point)
        excess = float(np.max(np.abs(gait.eigenvalues))) - 1
        if excess >= 0:
            high = slope
        else:
            low = slope
        if abs(excess) < 1e-12 or high - low < 1e-13:
            break
        newton = slope - excess / sensitivity.spectral_radius["slope"]
        slope = newton if low < newton < high else (low + high) / 2
    return slope, gait


def compass_cycle(dynamics, y0, period, samples=400):
    """One step of the compass gait from `y0`, sampled, and the post-impact state."""
    term = diffrax.ODETerm(lambda t, y, args: dynamics.vector_field(t, y, jnp.zeros(1)))
    ts = jnp.linspace(0.0, period, samples)
    solution = diffrax.diffeqsolve(
        term, diffrax.Dopri8(), 0.0, period, None, jnp.asarray(y0), saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=100_000,
    )
    return np.asarray(solution.ys)


def plot(result, cycle, out):
    from lerax_like.analysis import pyplot

    plt = pyplot()
    figure, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    simplest = result["simplest_walker"]
    for name, style in (("long_period", "-"), ("short_period", "--")):
        branch = simplest[name]
        slopes = np.array([point["slope"] for point in branch])
        angles = np.array([point["fixed_point"][0] for point in branch])
        stable = np.array([point["spectral_radius"] < 1 for point in branch])
        label = "long-period gait" if name == "long_period" else "short-period gait (unstable)"
        axes[0].plot(slopes, angles, style, color="tab:blue" if name == "long_period" else "tab:red", label=label)
        axes[0].plot(slopes[~stable], angles[~stable], "x", color="black", markersize=3)
    doubling = simplest["period_doubling"]
    axes[0].axvline(doubling["slope"], color="gray", linestyle=":", label=f"first period doubling, gamma = {doubling['slope']:.5f}")
    axes[0].set_xlabel("slope gamma (rad)")
    axes[0].set_ylabel("stance angle theta* just after heel strike (rad)")
    axes[0].set_title("Simplest walker: period-one gaits (x: unstable)")
    axes[0].legend(fontsize=8)
    axes[1].plot(cycle[:, 0], cycle[:, 2], color="tab:blue", label="stance leg")
    axes[1].plot(cycle[:, 1], cycle[:, 3], color="tab:orange", label="swing leg")
    for leg, other in ((0, 1), (1, 0)):  # the heel strike: the legs exchange, their rates jump
        axes[1].plot([cycle[-1, leg], cycle[0, other]], [cycle[-1, 2 + leg], cycle[0, 2 + other]], ":", color="gray", label="heel strike" if leg == 0 else None)
    axes[1].set_xlabel("leg angle from the vertical (rad)")
    axes[1].set_ylabel("rate (rad/s)")
    axes[1].set_title("Compass gait, nominal (3 deg): limit cycle")
    axes[1].legend(fontsize=8)
    figure.tight_layout()
    figure.savefig(out / "walkers.png", dpi=120)


def main(argv=None):
    parser = benchmark_parser(__doc__, quick="a coarser grid of slopes")
    arguments = parser.parse_args(argv)
    out = output_folder(arguments)
    start = time.perf_counter()
    simplest = lambda gamma: SimplestWalkerDynamics(slope=gamma)
    count = 6 if arguments.quick else 12
    result = {"simplest_walker": {}, "compass_gait": {}}
    reference = 0.009
    for name, (theta, theta_dot) in (("long_period", (0.2003109005, -0.1998324730)), ("short_period", (0.1939373696, -0.2038669273))):
        gait = find_gait(simplest(reference), simplest(reference).on_section(theta, theta_dot))
        up = continue_in_slope(simplest, gait, np.linspace(reference, 0.0195, count))
        down = continue_in_slope(simplest, gait, np.geomspace(reference, 1e-4, count)[1:])
        result["simplest_walker"][name] = down[::-1] + up
        print(f"simplest walker, {name}: {len(down) + len(up)} gaits, slopes {down[-1]['slope'] if down else reference:.2e} to {up[-1]['slope']:.4f}")
    long_branch = result["simplest_walker"]["long_period"]
    below = max((point for point in long_branch if point["spectral_radius"] < 1), key=lambda point: point["slope"])
    gamma, gait = period_doubling(simplest, below["slope"], np.asarray(below["fixed_point"]))
    result["simplest_walker"]["period_doubling"] = {**_record(gamma, gait)}
    print(f"simplest walker: first period doubling at gamma = {gamma:.8f} (eigenvalues {gait.eigenvalues[:2]})")

    nominal = CompassGaitDynamics()
    gait = find_gait(nominal, jnp.asarray([-0.2187, 0.3234, 1.0924, 0.3774]))
    sensitivity = gait_sensitivity(nominal, gait)
    result["compass_gait"]["nominal"] = {
        **_record(float(nominal.slope), gait),
        "d_fixed_point": {name: value.tolist() for name, value in sensitivity.fixed_point.items()},
        "d_spectral_radius": sensitivity.spectral_radius,
    }
    compass = lambda slope: CompassGaitDynamics(slope=slope)
    slopes = np.deg2rad(np.linspace(3.0, 6.0, 4 if arguments.quick else 7))
    branch = continue_in_slope(compass, gait, slopes)
    result["compass_gait"]["branch"] = branch
    below = max((point for point in branch if point["spectral_radius"] < 1), key=lambda point: point["slope"])
    slope, doubling = period_doubling(compass, below["slope"], np.asarray(below["fixed_point"]))
    result["compass_gait"]["period_doubling"] = {**_record(slope, doubling), "slope_degrees": float(np.rad2deg(slope))}
    print(f"compass gait: gait {gait.fixed_point}, period {gait.period:.10f}, eigenvalues {gait.eigenvalues}")
    print(f"compass gait: first period doubling at {np.rad2deg(slope):.6f} deg (eigenvalues {doubling.eigenvalues[:2]})")
    result["seconds_including_compile"] = time.perf_counter() - start
    (out / "walkers.json").write_text(json.dumps(result, indent=2) + "\n")
    try:
        plot(result, compass_cycle(nominal, gait.fixed_point, gait.period), out)
    except ImportError:
        print("no matplotlib: no figure")


if __name__ == "__main__":
    main()
