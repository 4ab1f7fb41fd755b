"""A reference for hybrid (impacting) flows, computed independently of diffrax with SciPy.

`solve_ivp` integrates the smooth flow with `events`, one per contact surface `gap(y) = 0`
crossed downwards (the gap closing); at the first located event the solve stops, the
impact map is applied and a fresh solve restarts from the impact time. Restarting, rather
than integrating across the jump, keeps the reference's order: a Runge-Kutta step that
straddles a jump in the state is first-order at best.

Right after an impact the state sits on (or a rounding error beyond) the surface it left,
moving away from it. SciPy's event test counts a downward crossing only from `gap >= 0` to
`gap <= 0` between two steps, so a gap that starts at zero (or a rounding error below)
and opens is not an event, and the surface stays armed for a later return. A restart
whose gap is closed and still closing (a resting contact, which this reference does not
model) is refused.
"""

from collections.abc import Callable, Sequence
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .reference import scipy_solve_ivp


class Contact(NamedTuple):
    """A contact surface `gap(y) >= 0` and the impact map applied where the gap closes."""

    gap: Callable
    impact: Callable


class HybridSolution(NamedTuple):
    """The state at the end, the impacts' times and which contact each was, and the segments."""

    y: np.ndarray
    event_times: np.ndarray
    event_contacts: np.ndarray
    segments: list


# Impacts in one solve, past which `hybrid_reference` reports a Zeno run.
MAX_EVENTS = 1000


class _Programs(NamedTuple):
    """A flow's vector field `(t0, s, y, u)` (the field at time `t0 + s`), and each contact's
    gap `(y)`, closing rate `(t0, y, u)` and impact map `(y)`, each a `jax.jit` program."""

    field: Callable
    gaps: list[Callable]
    closing_rates: list[Callable]
    impacts: list[Callable]


def _programs(vector_field: Callable, contacts: Sequence[Contact]) -> _Programs:
    """`vector_field(t, y, u)` and the contacts compiled once, the step's start `t0` and the
    input `u` arguments: one set of programs serves every env step of a rollout."""

    def field(t0, s, y, u):
        return vector_field(t0 + s, y, u)

    return _Programs(
        field=jax.jit(field),
        # (Wrapped: a bound method of an Equinox module, which holds arrays, cannot key `jax.jit`'s cache.)
        gaps=[jax.jit(lambda y, gap=contact.gap: gap(y)) for contact in contacts],
        closing_rates=[
            jax.jit(lambda t0, y, u, gap=contact.gap: jax.jvp(gap, (y,), (field(t0, 0.0, y, u),))[1]) for contact in contacts
        ],
        impacts=[jax.jit(lambda y, impact=contact.impact: impact(y)) for contact in contacts],
    )


def hybrid_reference(
    vector_field: Callable,
    contacts: Sequence[Contact],
    y0,
    u,
    t1: float,
    *,
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float = 1e-12,
    max_events: int = MAX_EVENTS,
    dense_output: bool = False,
) -> HybridSolution:
    """Integrate `dy/dt = vector_field(t, y, u)` over `[0, t1]` through every impact.

    `vector_field`, each contact's `gap` and `impact` are JAX functions (jitted here and
    called from NumPy in float64). Raises when `max_events` impacts do not reach `t1`
    (a Zeno run), or when a solve fails: a reference never hides a failure.
    `segments` holds each segment's `solve_ivp` solution (dense if `dense_output`).
    """
    with jax.enable_x64(True):
        programs = _programs(vector_field, contacts)
    return _hybrid_solve(
        programs, 0.0, y0, u, t1, method=method, rtol=rtol, atol=atol, max_events=max_events, dense_output=dense_output
    )


def _hybrid_solve(
    programs: _Programs, t0, y0, u, t1: float, *, method: str, rtol: float, atol: float, max_events: int,
    dense_output: bool,
) -> HybridSolution:
    """`hybrid_reference` of compiled `programs`, the field read at `t0 + t`."""
    solve_ivp = scipy_solve_ivp()
    with jax.enable_x64(True):
        u = jnp.asarray(u, dtype=jnp.float64)
        t0 = jnp.asarray(t0, dtype=jnp.float64)
        gaps, closing_rates, impacts = programs.gaps, programs.closing_rates, programs.impacts

        def rhs(t, y):
            return np.asarray(programs.field(t0, np.float64(t), y, u))

        def event(index):
            def closing(t, y):
                return float(gaps[index](y))

            closing.terminal = True
            closing.direction = -1.0
            return closing

        t = 0.0
        y = np.asarray(y0, dtype=np.float64)
        times: list[float] = []
        which: list[int] = []
        segments = []
        while True:
            for index, gap in enumerate(gaps):
                # A plastic impact leaves the gap closed and not opening: a resting contact.
                if float(gap(y)) <= 0 and float(closing_rates[index](t0, y, u)) <= 0:
                    raise RuntimeError(
                        f"hybrid reference: at t={t} contact {index}'s gap is closed ({float(gap(y)):.3g}) and "
                        "closing, a resting contact that this reference does not model"
                    )
            armed = list(range(len(gaps)))
            solution = solve_ivp(
                rhs, (t, float(t1)), y, method=method, rtol=rtol, atol=atol,
                events=[event(i) for i in armed], dense_output=dense_output,
            )
            if solution.status == -1:
                raise RuntimeError(f"hybrid reference solve ({method}) failed at t={t}: {solution.message}")
            segments.append(solution)
            hits = [(solution.t_events[k][0], armed[k]) for k in range(len(armed)) if len(solution.t_events[k])]
            if not hits:
                return HybridSolution(solution.y[:, -1], np.asarray(times), np.asarray(which, dtype=int), segments)
            t, index = min(hits)
            k = armed.index(index)
            y = np.asarray(impacts[index](solution.y_events[k][0]))
            times.append(float(t))
            which.append(index)
            if len(times) >= max_events:
                raise RuntimeError(f"hybrid reference: {max_events} impacts before t={t1} (Zeno?)")


def contacts_of(env) -> list[Contact]:
    """An env's contact add-ons (`env.contacts`) as one `Contact` per surface, in the env's order."""
    dynamics = env.dynamics
    contacts = []
    for add_on in env.contacts:
        size = jax.eval_shape(lambda y, a=add_on: a.gaps(dynamics, y), env.initial(key=jax.random.key(0)).y).shape[0]
        for surface in range(size):
            contacts.append(Contact(
                gap=lambda y, a=add_on, i=surface: a.gaps(dynamics, y)[i],
                impact=lambda y, a=add_on, i=surface: a.impact(dynamics, y, i),
            ))
    return contacts


def hybrid_reference_trajectories(
    env, y0s, inputs, dt: float, fractions, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """As `dense_reference_trajectories`, through the impacts of the env's contacts: one hybrid
    solve per initial state and env step (the field read at the episode's time `k dt + s`),
    each restarted at every impact (`segmented_trajectories`)."""
    # Compiled once for the rollout (each step's start `t0` and input are arguments): made
    # afresh for every env step, its programs took about 90 ms a step to trace and compile.
    with jax.enable_x64(True):
        programs = _programs(env.physics.vector_field, contacts_of(env))

    def step(k: int, y, u):
        t0 = np.float64(k) * np.float64(dt)
        solution = _hybrid_solve(
            programs, t0, y, u, dt, method=method, rtol=rtol, atol=atol, max_events=MAX_EVENTS, dense_output=len(fractions) > 0,
        )
        return solution.y, solution.segments

    return segmented_trajectories(step, y0s, inputs, dt, fractions)


def segmented_trajectories(step: Callable, y0s, inputs, dt: float, fractions) -> tuple[np.ndarray, np.ndarray]:
    """The states after each env step `(B, T, n)` and at `fractions` of each step `(B, T,
    len(fractions), n)` of the initial states `y0s` under `inputs` (one held per env step).

    `step(k, y, u)` solves env step `k` from `y` and returns its end state and its `solve_ivp`
    segments (dense where `fractions` are asked), from which each time inside is read.
    """
    y0s = np.asarray(y0s, dtype=np.float64)
    inputs = np.asarray(inputs, dtype=np.float64)
    fractions = np.asarray(fractions, dtype=np.float64)
    states = np.empty((len(y0s), len(inputs), y0s.shape[1]))
    inside = np.empty((len(y0s), len(inputs), len(fractions), y0s.shape[1]))
    for b, y in enumerate(y0s):
        for k, u in enumerate(inputs):
            y, segments = step(k, y, u)
            for j, time in enumerate(fractions * dt):
                segment = next(s for s in segments if s.t[0] <= time <= s.t[-1])
                inside[b, k, j] = segment.sol(time)
            states[b, k] = y
    return states, inside


__all__ = [
    "Contact", "HybridSolution", "contacts_of", "hybrid_reference", "hybrid_reference_trajectories", "segmented_trajectories",
]
