"""Stability on stiff and extreme cases: case x solver -> status, steps, error.

    python -m benchmarks stability            # writes benchmarks/results/stability.{csv,md}
    python -m benchmarks stability --quick    # three cases, three solvers, a short root-finder run, into results/quick/
    python -m benchmarks.stability [--only CASE] [--out DIR]

Every case is a scene built with the solver, run with constant actions from a fixed
state; each env step's solve is checked (`solver_ok`) and the trajectory, sampled at
the env steps, is compared with SciPy (DOP853, or Radau for the stiff cases, at
rtol = atol = 1e-12; across the end stops the reference is event-split: integrated piece
by piece between the contact events found by `solve_ivp`'s event location, as one
Radau solve across the non-smooth stops is wrong by O(1)).

Status:
- `refused`: the scene refused the parameters or the solver at construction;
- `non-finite`: an env step met a non-finite state (flagged, episode ended);
- `budget exhausted`: an adaptive solve ran out of steps (flagged, episode ended);
- `solver failed`: a fixed-step Newton solve did not converge (flagged);
- `inaccurate`: every step succeeded, relative error > 1e-3;
- `ok`: every step succeeded, relative error <= 1e-3.

The error is max over the env steps of |y - y_ref|_inf, over max |y_ref|_inf.

Also compares Kvaerno5's root finders on Van der Pol (mu = 1e3) and writes
`root_finders.{csv,md}`. Timings are from a shared 2-core machine:
indicative only, compare within one run.
"""

import argparse
import csv
import dataclasses
import functools
import math
import pathlib
import time
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix
from scipy.integrate import solve_ivp

import lerax_like as ll
from benchmarks import results_dir


jax.config.update("jax_enable_x64", True)

SOLVERS = ("euler", "rk4", "tsit5", "implicit_euler", "kvaerno3", "kvaerno5")
TOLERANCE = 1e-3


# --- references ------------------------------------------------------------------------

def cartpole_field(p, force, mode=None):
    """The cart-pole vector field in NumPy (the physics is checked against SymPy in
    tests/test_stiff.py; here it only feeds SciPy).

    `mode=None` picks the end-stop force from the state, as the package does. A contact
    mode (`"free"`, `"right"`, `"left"`: pushing stop) gives each smooth piece of the
    field, extended across its boundary, for the event-split reference.
    """
    g, mc, m, l, b, k, c, limit = (
        p["gravity"], p["cart_mass"], p["pole_mass"], p["half_length"], p["joint_damping"],
        p["end_stop_stiffness"], p["end_stop_damping"], p["track_limit"],
    )

    def field(t, y):
        x, x_dot, theta, theta_dot = y
        stop = 0.0
        if mode == "right":
            stop = -(k * (x - limit) + c * x_dot)
        elif mode == "left":
            stop = k * (-limit - x) - c * x_dot
        elif mode is None and x > limit:
            stop = -max(k * (x - limit) + c * x_dot, 0.0)
        elif mode is None and x < -limit:
            stop = max(k * (-limit - x) - c * x_dot, 0.0)
        total = mc + m
        sin, cos = math.sin(theta), math.cos(theta)
        temp = (force + stop + m * l * theta_dot**2 * sin) / total
        theta_acc = (g * sin - cos * temp - b * theta_dot / (m * l)) / (l * (4 / 3 - m * cos**2 / total))
        x_acc = temp - m * l * theta_acc * cos / total
        return [x_dot, x_acc, theta_dot, theta_acc]

    return field


def plain_reference(field, y0, times, method):
    solution = solve_ivp(field, (0.0, times[-1]), y0, method=method, rtol=1e-12, atol=1e-12, t_eval=times)
    if not solution.success:
        raise RuntimeError(solution.message)
    return solution.y.T


def event_split_reference(parameters, force, y0, times):
    """Integrate piece by piece between the contact events, restarting at each one.

    A small hybrid automaton: off the stops (`free`) the cart can enter either stop;
    on a stop that pushes (`right`/`left`) the push `k p + c p'` can fall to zero
    (released: a damper cannot pull) or, with `c = 0`, the cart leaves; released inside
    a stop, it can leave or be pushed again. Each piece integrates that mode's smooth
    field with DOP853 at 1e-12; `solve_ivp`'s event location finds the switch.
    """
    k, c, limit = parameters["end_stop_stiffness"], parameters["end_stop_damping"], parameters["track_limit"]

    def event(function, direction):
        function.terminal, function.direction = True, direction
        return function

    right_gap = lambda t, y: y[0] - limit
    left_gap = lambda t, y: y[0] + limit
    right_push = lambda t, y: k * (y[0] - limit) + c * y[1]
    left_push = lambda t, y: k * (-limit - y[0]) - c * y[1]
    # mode -> field mode and [(event, direction, next mode)]
    automaton = {
        "free": ("free", [(right_gap, 1.0, "right"), (left_gap, -1.0, "left")]),
        "right": ("right", [(right_push, -1.0, "right released"), (right_gap, -1.0, "free")]),
        "left": ("left", [(left_push, -1.0, "left released"), (left_gap, 1.0, "free")]),
        "right released": ("free", [(right_gap, -1.0, "free"), (right_push, 1.0, "right")]),
        "left released": ("free", [(left_gap, 1.0, "free"), (left_push, 1.0, "left")]),
    }
    mode, t, y, out, events = "free", 0.0, np.asarray(y0, dtype=float), [], 0
    remaining = list(times)
    while remaining:
        field_mode, transitions = automaton[mode]
        solution = solve_ivp(
            cartpole_field(parameters, force, field_mode), (t, remaining[-1]), y, method="DOP853",
            rtol=1e-12, atol=1e-12, t_eval=remaining,
            events=[event(function, direction) for function, direction, _ in transitions],
        )
        if not solution.success:
            raise RuntimeError(solution.message)
        if len(solution.t):
            out.extend(np.asarray(solution.y).T)
        remaining = remaining[len(solution.t):]
        if solution.status != 1:
            break
        events += 1
        hit = next(i for i, ts in enumerate(solution.t_events) if len(ts))
        t, y = solution.t_events[hit][0], solution.y_events[hit][0].copy()
        mode = transitions[hit][2]
        # With c = 0 the push and the gap vanish together: released is already free.
        if mode == "right released" and y[0] <= limit or mode == "left released" and y[0] >= -limit:
            mode = "free"
    return np.asarray(out), events


# --- cases ---------------------------------------------------------------------------

@dataclasses.dataclass
class Case:
    name: str
    description: str
    make: Callable[[str], ll.AbstractEnv]  # solver preset -> env (may raise: refused)
    y0: list
    steps: int
    action: float
    reference: Callable[[np.ndarray], np.ndarray] | None  # env-step times -> states
    float32: bool = False
    skip: tuple = ()


CARTPOLE_DEFAULTS = dict(
    gravity=9.8, cart_mass=1.0, pole_mass=0.1, half_length=0.5, joint_damping=0.0,
    end_stop_stiffness=0.0, end_stop_damping=0.0, track_limit=2.4,
)


def cartpole_case(name, description, *, dt=0.02, steps=200, action=0.0, y0=(0.0, 0.0, 0.2, 0.0),
                  force_mag=10.0, contact=False, float32=False, skip=(), **overrides):
    parameters = {**CARTPOLE_DEFAULTS, **overrides}

    def make(solver):
        return ll.make("CartPoleContinuous",
            **parameters, force_mag=force_mag, dt=dt, solver=solver,
            theta_threshold_radians=math.inf, x_threshold=math.inf, max_episode_steps=None,
        )

    field = cartpole_field(parameters, force_mag * action)

    @functools.lru_cache
    def cached(key):
        times = np.asarray(key)
        if contact:
            return event_split_reference(parameters, force_mag * action, list(y0), times)[0]
        return plain_reference(field, list(y0), times, "DOP853")

    def reference(times):
        return cached(tuple(times))

    return Case(name, description, make, list(y0), steps, action, reference, float32, skip)


def van_der_pol_case(name, description, mu, dt, steps, y0=(2.0, 0.0)):
    def make(solver):
        return ll.make("VanDerPol", mu=mu, dt=dt, solver=solver, max_episode_steps=None)

    def field(t, y):
        return [y[1], mu * (1 - y[0] ** 2) * y[1] - y[0]]

    def jacobian(t, y):
        return [[0.0, 1.0], [-2 * mu * y[0] * y[1] - 1, mu * (1 - y[0] ** 2)]]

    def reference(times):
        solution = solve_ivp(field, (0.0, times[-1]), list(y0), method="Radau", rtol=1e-12, atol=1e-12,
                             t_eval=times, jac=jacobian)
        return solution.y.T

    return Case(name, description, make, list(y0), steps, 0.0, reference)


def horizon_cases(horizon, skip):
    """The same long run in float64 and float32, sharing one reference."""
    f64 = cartpole_case(f"horizon {horizon:g} f64", f"defaults, {horizon} steps, float64",
                        steps=horizon, skip=skip)
    f32 = dataclasses.replace(f64, name=f"horizon {horizon:g} f32",
                              description=f"defaults, {horizon} steps, float32", float32=True)
    return [f64, f32]


QUICK_CASES = ("cartpole baseline", "pole mass 0", "joint damping 300")
QUICK_SOLVERS = ("euler", "tsit5", "kvaerno5")


def cases(quick: bool) -> list[Case]:
    horizon = 2_000 if quick else 100_000
    slow = ("implicit_euler", "kvaerno3", "kvaerno5")
    every = [
        cartpole_case("cartpole baseline", "defaults, dt 0.02, 4 s"),
        cartpole_case("dt 0.5", "defaults, dt 0.5, 100 s", dt=0.5, steps=200),
        cartpole_case("pole mass 1e-6", "pole_mass 1e-6", pole_mass=1e-6),
        cartpole_case("pole mass 1e3", "pole_mass 1e3", pole_mass=1e3),
        cartpole_case("pole length 1e-2", "half_length 5e-3 (pole 1 cm)", half_length=5e-3),
        cartpole_case("pole length 1e2", "half_length 50 (pole 100 m)", half_length=50.0),
        cartpole_case("cart mass 1e-4", "cart_mass 1e-4", cart_mass=1e-4),
        cartpole_case("pole mass 0", "pole_mass 0: invalid (massless pole)", pole_mass=0.0),
        cartpole_case("stiffness -1", "end_stop_stiffness -1: invalid", end_stop_stiffness=-1.0),
        cartpole_case("force 1e4", "force_mag 1e4, action 1", force_mag=1e4, action=1.0),
        cartpole_case("joint damping 300", "joint_damping 300 (eigenvalue -9.7e3)", joint_damping=300.0),
        cartpole_case(
            "end stops 1e6", "stops at +-0.5 m, k 1e6, c 200, cart at 1 m/s (contact)",
            end_stop_stiffness=1e6, end_stop_damping=200.0, track_limit=0.5, y0=(0.0, 1.0, 0.2, 0.0),
            contact=True,
        ),
        van_der_pol_case("van der pol mu 1", "mu 1, dt 0.05, 10 s", 1.0, 0.05, 200),
        van_der_pol_case("van der pol mu 1e3", "mu 1e3, dt 10, 3000 s", 1000.0, 10.0, 300),
        *horizon_cases(horizon, slow),
    ]
    return [case for case in every if case.name in QUICK_CASES] if quick else every


# --- running -------------------------------------------------------------------------

@eqx.filter_jit
def run(env, y0, action, steps_array):
    """Env steps via the integrator, keeping the raw end state of each solve."""
    u = env.physical_input(action)

    def body(carry, _):
        y, alive = carry
        raw, info = env.integrator.integrate(env.physics.vector_field, y, u, env.dt)
        ok = info["solver_ok"] & alive
        next_y = jnp.where(ok, raw, y)
        record = (next_y, ok, jnp.all(jnp.isfinite(raw)), info["solver_steps"])
        return (next_y, ok), record

    _, (ys, ok, finite, solver_steps) = jax.lax.scan(body, (y0, jnp.asarray(True)), steps_array)
    return ys, ok, finite, solver_steps


def run_case(case: Case, solver: str) -> dict:
    row = dict(case=case.name, description=case.description, solver=solver)
    if solver in case.skip:
        return {**row, "status": "not run", "steps": "", "error": "", "failed_at": "", "seconds": ""}
    context = jax.enable_x64(False) if case.float32 else jax.enable_x64(True)
    with context:
        try:
            env = case.make(solver)
        except ValueError as error:
            return {**row, "status": "refused", "steps": "", "error": "", "failed_at": "",
                    "seconds": "", "note": str(error)[:80]}
        y0 = jnp.asarray(case.y0, dtype=env.dt.dtype)
        action = jnp.full((1,), case.action, dtype=env.dt.dtype)
        dummy = jnp.zeros((case.steps,), dtype=env.dt.dtype)
        jax.block_until_ready(run(env, y0, action, dummy))  # compile
        start = time.perf_counter()
        ys, ok, finite, solver_steps = jax.block_until_ready(run(env, y0, action, dummy))
        seconds = time.perf_counter() - start
    ys, ok, finite, solver_steps = map(np.asarray, (ys, ok, finite, solver_steps))
    total_steps = int(solver_steps[ok].sum())
    if not ok.all():
        first = int(np.argmin(ok))
        if not finite[first]:
            status = "non-finite"
        elif env.integrator.adaptive:
            status = "budget exhausted"
        else:
            status = "solver failed"
        return {**row, "status": status, "steps": total_steps, "error": "", "failed_at": first + 1,
                "seconds": f"{seconds:.3g}"}
    times = float(env.dt) * np.arange(1, case.steps + 1)
    reference = case.reference(times)
    error = float(np.max(np.abs(ys.astype(np.float64) - reference)) / np.max(np.abs(reference)))
    status = "ok" if error <= TOLERANCE else "inaccurate"
    return {**row, "status": status, "steps": total_steps, "error": f"{error:.2e}", "failed_at": "",
            "seconds": f"{seconds:.3g}"}


def root_finders(t1: float = 3000.0) -> list[dict]:
    """Kvaerno5 on Van der Pol mu = 1e3 from [2, 0] over [0, t1], one solve per root finder."""
    dynamics = ll.VanDerPolDynamics(mu=1000.0)
    controller = diffrax.PIDController(rtol=1e-6, atol=1e-9)
    choices = {
        "VeryChord (diffrax default)": diffrax.Kvaerno5(),
        "Chord, controller tolerances (preset)": diffrax.Kvaerno5(
            root_finder=diffrax.with_stepsize_controller_tols(optimistix.Chord)()
        ),
        "Newton, controller tolerances": diffrax.Kvaerno5(
            root_finder=diffrax.with_stepsize_controller_tols(optimistix.Newton)()
        ),
    }
    reference = van_der_pol_case("", "", 1000.0, t1, 1).reference(np.array([t1]))[-1]
    rows = []
    for name, solver in choices.items():
        @eqx.filter_jit
        def solve(solver):
            return diffrax.diffeqsolve(
                diffrax.ODETerm(dynamics.vector_field), solver, 0.0, t1, None, jnp.array([2.0, 0.0]),
                args=jnp.zeros(1), stepsize_controller=controller, max_steps=100_000, throw=False,
            )

        jax.block_until_ready(solve(solver))
        start = time.perf_counter()
        solution = jax.block_until_ready(solve(solver))
        seconds = time.perf_counter() - start
        error = float(np.max(np.abs(np.asarray(solution.ys[-1]) - reference)) / np.max(np.abs(reference)))
        rows.append(dict(
            root_finder=name, success=bool(solution.result == diffrax.RESULTS.successful),
            steps=int(solution.stats["num_steps"]), accepted=int(solution.stats["num_accepted_steps"]),
            rejected=int(solution.stats["num_rejected_steps"]), error=f"{error:.2e}", seconds=f"{seconds:.3g}",
        ))
        print(rows[-1], flush=True)
    return rows


def contact_reference_gap() -> list[str]:
    """How far a plain Radau solve across the end stops lands from the event-split one."""
    lines = []
    for damping in (0.0, 200.0):
        parameters = {**CARTPOLE_DEFAULTS, "end_stop_stiffness": 1e6, "end_stop_damping": damping,
                      "track_limit": 0.5}
        y0 = [0.0, 1.0, 0.2, 0.0]
        times = 0.02 * np.arange(1, 201)
        split, events = event_split_reference(parameters, 0.0, y0, times)
        plain = plain_reference(cartpole_field(parameters, 0.0), y0, times, "Radau")
        gap = float(np.max(np.abs(plain - split)) / np.max(np.abs(split)))
        lines.append(
            f"stiffness 1e6, damping {damping:g}: {events} events in 4 s; plain Radau at 1e-12 "
            f"vs event-split DOP853: relative gap {gap:.2e}"
        )
    return lines


def write(rows, path, columns):
    with open(path.with_suffix(".csv"), "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def markdown_table(rows, columns) -> str:
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(str(row.get(c, "")) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true",
        help=f"cases {', '.join(QUICK_CASES)}; solvers {', '.join(QUICK_SOLVERS)}; root finders to t = 300",
    )
    parser.add_argument("--only", default=None, help="run only cases whose name contains this")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    arguments = parser.parse_args(argv)
    out = arguments.out or results_dir(arguments.quick)
    out.mkdir(parents=True, exist_ok=True)

    solvers = QUICK_SOLVERS if arguments.quick else SOLVERS
    finders_t1 = 300.0 if arguments.quick else 3000.0
    finders = root_finders(finders_t1)
    write(finders, out / "root_finders", list(finders[0]))

    gap = contact_reference_gap()
    print(gap, flush=True)
    gap = "; ".join(gap)

    rows = []
    for case in cases(arguments.quick):
        if arguments.only and arguments.only not in case.name:
            continue
        for solver in solvers:
            row = run_case(case, solver)
            print(row, flush=True)
            rows.append(row)
    columns = ["case", "description", "solver", "status", "steps", "error", "failed_at", "seconds"]
    write(rows, out / "stability", columns)

    grid = ["| case | " + " | ".join(solvers) + " |", "|---|" + "---|" * len(solvers)]
    for case in dict.fromkeys(row["case"] for row in rows):
        cells = []
        for solver in solvers:
            row = next(r for r in rows if r["case"] == case and r["solver"] == solver)
            cell = row["status"]
            if row["error"]:
                cell += f" ({row['error']})"
            elif row["failed_at"]:
                cell += f" (step {row['failed_at']})"
            cells.append(cell)
        grid.append(f"| {case} | " + " | ".join(cells) + " |")
    text = [
        "# Stability on stiff and extreme cases",
        "",
        "Written by `python -m benchmarks stability" + (" --quick" if arguments.quick else "") + "`.",
        "Status per case and solver (presets: fixed-step `euler`, `rk4`; adaptive `tsit5`,",
        "`implicit_euler`, `kvaerno3`, `kvaerno5` with a PIDController, max_steps 4096 per env",
        "step), with the relative error against SciPy (1e-12) or the env step at which the run",
        f"failed. ok: error <= {TOLERANCE:g}. Cart-pole cases: zero force unless stated, theta0 = 0.2,",
        "termination bounds infinite. `not run`: implicit solvers skipped on the 1e5-step horizons",
        "(minutes each on this machine).",
        "",
        "\n".join(grid),
        "",
        "Contact reference: " + gap + ".",
        "",
        "## Details",
        "",
        markdown_table(rows, columns),
        "",
        f"## Kvaerno5 root finders (Van der Pol, mu = 1e3, [0, {finders_t1:g}], rtol 1e-6, atol 1e-9)",
        "",
        markdown_table(finders, list(finders[0])),
        "",
    ]
    (out / "stability.md").write_text("\n".join(text))
    (out / "root_finders.md").write_text(
        f"# Kvaerno5 root finders on Van der Pol (mu = 1e3, t in [0, {finders_t1:g}])\n\n" + markdown_table(finders, list(finders[0])) + "\n"
    )


if __name__ == "__main__":
    main()
