"""An env step solved segment by segment, each up to its first located event: what the impact
step (`lerax_like.hybrid`) and the stick-slip step (`lerax_like.stick_slip`) share.

Each builds its vector field, event condition and what happens at an event; the solve of one
segment (the term for the scene's solver, the step budget, the adjoint, the grazing guard on an
adaptive step, an idle finished env of a batch), the scan over segments and the step's final
checks are written here, once.
"""

from collections.abc import Callable
from typing import Any, NamedTuple, final

import diffrax
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import optimistix

from ._types import Array, BoolScalar, IntScalar, Scalar, State
from .integrate import GuardedPIDController, Integrator, ProjectedODETerm, SemiImplicitEuler


# The share of `dt` that an env which has finished its step integrates again, discarded, while
# the other envs of a vmapped batch finish theirs (`solve_segment`): any positive share keeps
# that solve finite; a small one keeps it to one step.
IDLE_FRACTION = 2.0**-10


@final
class GrazingGuardController(GuardedPIDController):
    """A `PIDController` that also rejects a trial step over which a gap dips below zero and back.

    `guard(t0, t1, y0, y1, args)` says where, as a fraction of the step, the cubic Hermite
    interpolant of some gap dips below zero with both ends above it (1 where none does);
    the step is then retried up to there, where the event's sign change shows.
    """

    guard: Callable | None = None

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        keep, next_t0, next_t1, made_jump, state, result = super().adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
        )
        if self.guard is None:
            raise TypeError("GrazingGuardController needs its guard")
        fraction = self.guard(t0, t1, y0, y1_candidate, args)
        dip = fraction < 1
        keep = keep & ~dip
        next_t0 = jnp.where(dip, t0, next_t0)
        next_t1 = jnp.where(dip, t0 + fraction * (t1 - t0), next_t1)
        state = jax.tree.map(lambda new, old: jnp.where(dip, old, new), state, controller_state)
        return keep, next_t0, next_t1, made_jump, state, result


def hermite_dip(g0, g1, m0, m1):
    """Where in `(0, 1)` the cubic Hermite `p` (values `g0`, `g1`, slopes `m0`, `m1`) is lowest, and `p` there.

    Only a minimum inside the step matters (`m0 < 0 < m1`): `p'(s) = a s^2 + b s + m0`.
    """
    a = 6 * g0 + 3 * m0 - 6 * g1 + 3 * m1
    b = -6 * g0 - 4 * m0 + 6 * g1 - 2 * m1
    # The root where p' turns from negative to positive is (-b + sqrt(D)) / (2a) whatever the
    # sign of a (for a < 0 the smaller root, for a > 0 the larger; a `sign(a)` here once
    # took the wrong one for a < 0, and a dip over a step was missed). Written as
    # 2 m0 / (-b - sqrt(D)) where b >= 0, which neither cancels nor divides by a (a = 0:
    # -m0 / b, the linear case).
    discriminant = b**2 - 4 * a * m0
    # Safe in reverse mode: no infinite derivative of sqrt at 0 in a branch `where` drops.
    root = jnp.where(discriminant > 0, jnp.sqrt(jnp.where(discriminant > 0, discriminant, 1.0)), 0.0)
    stable = -b - root
    safe_a = jnp.where(a == 0, 1.0, a)
    s = jnp.where(b >= 0, 2 * m0 / jnp.where(stable == 0, -1.0, stable), (-b + root) / (2 * safe_a))
    s = jnp.clip(jnp.where((b < 0) & (a == 0), 1.0, s), 0.0, 1.0)
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    return s, h00 * g0 + h10 * m0 + h01 * g1 + h11 * m1


@final
class TimeBisection(optimistix.Bisection):
    """Bisection that stops when the bracket in time is within tolerance, whatever the condition's value.

    `optimistix.Bisection` also asks `|condition| < atol`: a normal force of 10 N is
    computed to about 1e-15 N, never below `atol` = 4 machine epsilons, and the root find
    ran out of steps. The time bracket is what locates the switch.
    """

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        leaves = jax.tree.leaves(f_struct)
        return super().init(_one_condition(fn), y, args, options, leaves[0], aux_struct, tags)

    def step(self, fn, y, args, options, state, tags):
        return super().step(_one_condition(fn), y, args, options, state, tags)

    def terminate(self, fn, y, args, options, state, tags):
        del fn, args, options, tags
        scale = self.atol + self.rtol * jnp.abs(y)
        return jnp.abs(state.lower - state.upper) < scale, optimistix.RESULTS.successful


def _one_condition(fn) -> Any:
    """`fn` with several conditions' values summed: diffrax's root find zeroes all but the one
    that fired (`diffrax.Event` with a tuple of conditions), so the sum is that one; a single
    condition is passed through unchanged."""

    def condition(y, args):
        value, aux = fn(y, args)
        leaves = jax.tree.leaves(value)
        return (leaves[0] if len(leaves) == 1 else sum(leaves[1:], leaves[0])), aux

    return condition


class SegmentEnd(NamedTuple):
    """Where a segment ended: its state and time (the inputs, for an env already at `dt`), the
    solve's result, whether it succeeded (an event ends a segment successfully), its
    accepted and attempted steps (0 for an env already at `dt`), and which condition ended
    it (`diffrax.Solution.event_mask`, shaped as the conditions given: all False when none)."""

    y: State
    t: Scalar
    result: diffrax.RESULTS
    solved: BoolScalar
    accepted: IntScalar
    tried: IntScalar
    fired: Any = None


def segment_solver(
    integrator: Integrator,
    vector_field: Callable,
    velocity_indices: tuple[int, ...] | None,
    condition: Callable | tuple[Callable, ...],
    guard: Callable,
    dt: Scalar,
    *,
    root_finder: type[optimistix.Bisection] = optimistix.Bisection,
) -> Callable[[State, Scalar, Any], SegmentEnd]:
    """`solve(y, t, args)`: the solve from `(t, y)` towards `dt` that stops at the first zero of
    `condition` (a callable, or a tuple of them: `SegmentEnd.fired` says which), located by bisection to a few machine epsilons in time, falling only.

    An adaptive step of the integrator's `PIDController` is also checked by `guard`
    (`GrazingGuardController`), so that a short dip of a condition within a step is located.
    """
    adjoint = integrator.adjoint
    if isinstance(adjoint, diffrax.BacksolveAdjoint):
        raise ValueError(
            "adjoint BacksolveAdjoint cannot differentiate through located events (diffrax refuses "
            "events with it): use with_adjoint(env, 'checkpoint') (reverse mode) or 'forward' (jacfwd)"
        )
    solver = integrator.solver
    if isinstance(solver, SemiImplicitEuler):
        term = ProjectedODETerm(vector_field, velocity_indices=velocity_indices)
    else:
        term = diffrax.ODETerm(vector_field)
    controller = integrator.stepsize_controller_for(dt.dtype)
    if type(controller) in (diffrax.PIDController, GuardedPIDController):
        settings = {name: getattr(controller, name) for name in diffrax.PIDController.__dataclass_fields__}
        controller = GrazingGuardController(**settings, guard=guard)
    dt0 = dt / integrator.substeps if isinstance(controller, diffrax.ConstantStepSize) else None
    tolerance = 4 * float(jnp.finfo(dt.dtype).eps)
    event = diffrax.Event(condition, root_finder=root_finder(rtol=tolerance, atol=tolerance, flip=True), direction=False)

    def solve(y: State, t: Scalar, args) -> SegmentEnd:
        done = t >= dt
        # An env that has reached dt still runs this segment while another env of a vmapped
        # batch has not, and diffrax's step loop runs its steps too, their results dropped by
        # a select. Over the empty interval [dt, dt] those steps are not finite (diffrax
        # 0.7.2's ConstantStepSize divides by its number of steps, 0 there), and in reverse
        # mode the dropped value's zero cotangent times their infinite partial derivative is
        # NaN: the "double where" trap, which reached the event's implicit adjoint as lineax's
        # "non-finite input" (issue 29). So a finished env solves a short interval ending at
        # dt instead, from its own state, and its result is dropped here: finite by
        # construction, whatever the solver, controller and event.
        start = jnp.where(done, dt * (1 - IDLE_FRACTION), t)
        solution = diffrax.diffeqsolve(
            term, solver, t0=start, t1=dt, dt0=dt0, y0=y, args=args, stepsize_controller=controller,
            max_steps=integrator.max_steps, adjoint=adjoint, event=event, throw=False,
        )
        assert solution.ys is not None and solution.ts is not None  # diffeqsolve's default SaveAt(t1=True)
        result = solution.result
        return SegmentEnd(
            y=jnp.where(done, y, solution.ys[-1]),
            t=jnp.where(done, dt, solution.ts[-1]),
            result=result,
            solved=(result == diffrax.RESULTS.successful) | (result == diffrax.RESULTS.event_occurred),
            accepted=jnp.where(done, 0, solution.stats["num_accepted_steps"]),
            tried=jnp.where(done, 0, solution.stats["num_steps"]),
            fired=jax.tree.map(lambda fired: fired & ~done, solution.event_mask),
        )

    return solve


def scan_segments(solve_segment: Callable[[tuple], tuple], initial: tuple, segments: int, dt: Scalar) -> tuple:
    """Run `solve_segment` on a carry whose second entry is the time, `segments` times; the
    segments after every env's last one are skipped whole (`unvmap_any`: over a batch)."""

    def segment(carry, _):
        done = carry[1] >= dt
        return jax.lax.cond(eqxi.unvmap_any(~done), solve_segment, lambda carry: carry, carry), None

    final, _ = jax.lax.scan(segment, initial, None, length=segments)
    return final


def finish_step(
    y: State,
    t: Scalar,
    ok: BoolScalar,
    steps: IntScalar,
    rejected: IntScalar,
    dt: Scalar,
    projection: Callable[[State], State] | None,
) -> tuple[State, dict[str, Array]]:
    """The step's end state (projected, if the scene projects) and the info both steps give:
    `solver_ok` (every segment solved, `dt` reached, all finite: events left over when the
    budget ran out did not reach it), `solver_steps` and `solver_rejected_steps`."""
    finite = jnp.all(jnp.isfinite(y))
    if projection is not None:
        y = projection(y)
    ok = ok & (t >= dt) & finite & jnp.all(jnp.isfinite(y))
    return y, {"solver_ok": ok, "solver_steps": steps, "solver_rejected_steps": rejected}


__all__ = [
    "IDLE_FRACTION",
    "GrazingGuardController",
    "SegmentEnd",
    "TimeBisection",
    "finish_step",
    "hermite_dip",
    "scan_segments",
    "segment_solver",
]
