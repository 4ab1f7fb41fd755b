"""One env step of a scene with both located contacts and Coulomb friction: impacts and stick-slip
switches as two kinds of guard in one located-event loop (`lerax_like._segments`).

A segment runs in one friction mode (`lerax_like.stick_slip.FrictionModes`) and ends at the first
located zero of either guard: the friction's (a slip that ends, a release, a normal force that
changes sign, an inconsistent slip) or a contact's gap (`lerax_like.hybrid`). Which kind fired
is read from the solve (`diffrax.Solution.event_mask`, the guards given as a tuple); which of
the friction's four conditions fell is then read as in the friction step. At each segment's
start the contacts settle first (a state touching a surface and moving in is struck: the
impact map, then the re-placement just off the surface), and after an impact the friction mode
is read off the new state (moving: slipping that way; at rest: held if it can be).

Limits, reported and never silent: a rebound slower than `min_rebound_speed` would leave the
scene resting on a surface with friction acting, which this step does not model; the step then
fails (`info["solver_ok"]` False, `info["contact_rest"]` True). So do an inconsistent slip
(`info["friction_consistent"]`), a segment that fails, and a step needing more than the
friction's and the contacts' `max_events` together.
"""

from collections.abc import Callable, Sequence

import diffrax
import jax
import jax.numpy as jnp

from ._segments import TimeBisection, finish_step, hermite_dip, scan_segments, segment_solver
from ._types import Array, Input, ScalarLike, State
from .hybrid import _Surfaces
from .integrate import Integrator
from .physics import AbstractDynamics
from .physics.contact import AbstractContact
from .physics.friction import AbstractCoulombFriction
from .stick_slip import FrictionModes


def integrate_with_contacts_and_friction(
    integrator: Integrator,
    physics: AbstractDynamics,
    dynamics: AbstractDynamics,
    contacts: Sequence[AbstractContact],
    friction: AbstractCoulombFriction,
    y0: State,
    u: Input,
    dt: ScalarLike,
    *,
    projection: Callable[[State], State] | None = None,
    t0: ScalarLike = 0.0,
) -> tuple[State, dict[str, Array]]:
    """Solve over `[0, dt]` from `y0` with the contacts' impacts and the friction's switches located
    (module docstring); the vector field reads the episode's time `t0 + s`."""
    dtype = y0.dtype
    dt = jnp.asarray(dt, dtype=dtype)
    modes = FrictionModes(physics=physics, dynamics=dynamics, friction=friction, t0=t0)
    surfaces = _Surfaces(physics=physics, dynamics=dynamics, contacts=tuple(contacts), t0=jnp.asarray(t0, dtype=dtype))
    free = jnp.zeros_like(surfaces.gaps(y0), dtype=bool)

    def gap_condition(t, y, args, **kwargs):
        del t, args, kwargs
        return jnp.min(surfaces.gaps(y))

    def guard(t_start, t_end, y_start, y_end, args):
        # A gap's dip below zero and back within a trial step, along the friction's flow.
        step = t_end - t_start
        rates = lambda t, y: jax.jvp(surfaces.gaps, (y,), (modes.vector_field(t, y, args),))
        (g0, rate0), (g1, rate1) = rates(t_start, y_start), rates(t_end, y_end)
        s, lowest = hermite_dip(g0, g1, step * rate0, step * rate1)
        hidden = (g0 > 0) & (g1 > 0) & (rate0 < 0) & (rate1 > 0) & (lowest < 0)
        gaps = jax.lax.stop_gradient(jnp.min(jnp.where(hidden, jnp.clip(s, 1e-3, 0.999), 1.0)))
        return jnp.minimum(modes.guard(t_start, t_end, y_start, y_end, args), gaps)

    solve = segment_solver(
        integrator, modes.vector_field, physics.velocity_indices, (modes.condition, gap_condition), guard, dt,
        root_finder=TimeBisection,
    )

    def solve_segment(carry):
        y, t, mode, ended, which, ok, consistent, rest, steps, rejected, switches, first, impacts, first_impact = carry
        done = t >= dt
        struck, resting, hit, _ = surfaces.settle(t, y, u, free)
        y = jnp.where(done, y, struck)
        hit = hit & ~done
        hits = jnp.sum(hit, dtype=int)
        rest = rest | (jnp.any(resting) & ~done)
        # After an impact the friction's mode is read off the state, as at a step's start.
        settled, new_mode, fits = modes.settle(t, y, u, mode, ended & (hits == 0), which)
        y = jnp.where(done, y, settled)
        mode = jax.tree.map(lambda new, old: jnp.where(done, old, new), new_mode, mode)
        consistent = consistent & (done | fits)
        end = solve(y, t, (u, mode))
        event = (end.result == diffrax.RESULTS.event_occurred) & ~done
        friction_fired = event & end.fired[0]
        # Which of the friction's conditions fell: the one nearest zero (as `integrate_with_friction`).
        which = jnp.argmin(modes.conditions(end.t, end.y, (u, mode)))
        return (
            end.y,
            end.t,
            mode,
            friction_fired,
            which,
            ok & (done | end.solved),
            consistent,
            rest,
            steps + end.accepted,
            rejected + end.tried - end.accepted,
            switches + friction_fired.astype(int),
            jnp.where(friction_fired & (first == jnp.inf), end.t, first),
            impacts + hits,
            jnp.where((hits > 0) & (first_impact == jnp.inf), t, first_impact),
        )

    zero = jnp.zeros((), dtype=int)
    false, true, never = jnp.asarray(False), jnp.asarray(True), jnp.asarray(jnp.inf, dtype)
    mode = (jnp.zeros((), dtype), jnp.ones((), dtype))
    initial = (y0, jnp.zeros((), dtype), mode, false, zero, true, true, false, zero, zero, zero, never, zero, never)
    segments = friction.max_events + max(contact.max_events for contact in contacts) + 1
    final = scan_segments(jax.checkpoint(solve_segment, prevent_cse=False), initial, segments, dt)
    y, t, _, _, _, ok, consistent, rest, steps, rejected, switches, first, impacts, first_impact = final
    y, info = finish_step(y, t, ok & consistent & ~rest, steps, rejected, dt, projection)
    return y, info | {
        "switches": switches, "first_switch_time": first, "friction_consistent": consistent,
        "impacts": impacts, "first_impact_time": first_impact, "contact_rest": rest,
    }


__all__ = ["integrate_with_contacts_and_friction"]
