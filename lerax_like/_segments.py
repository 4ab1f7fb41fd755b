"""The one hybrid core: an env step solved segment by segment, each up to its first located event.

A hybrid system is an `AbstractModes`: its discrete mode, the vector field of each mode, its
guards (events) and its resets. Impacts (`lerax_like.hybrid.Surfaces`), Coulomb stick-slip
(`lerax_like.stick_slip.FrictionModes`), both together (`lerax_like.contact_friction`) and a
disk on a floor (`lerax_like.floor_contact`) are such systems, and `integrate_hybrid` is the
one loop that integrates them all; the walkers' return map (`lerax_like.analysis.gait`)
solves its stance phase with the same segment solve. Written here once: the solve of one
segment (the term for the scene's solver, the step budget, the adjoint, the grazing guard on
an adaptive step, an idle finished env of a batch), the located event, the scan over
segments, the counts of events by kind and the step's final checks.
"""

import abc
import functools
from collections.abc import Callable
from typing import Any, ClassVar, NamedTuple, final

import diffrax
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import optimistix

from ._types import Array, Bool, BoolScalar, Float, Input, IntScalar, Scalar, ScalarLike, State
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
        # A choice of step, as the controller's own: no derivative flows through it, or in.
        fraction = constant(self.guard)(*constant((t0, t1, y0, y1_candidate, args)))
        dip = fraction < 1
        keep = keep & ~dip
        next_t0 = jnp.where(dip, t0, next_t0)
        next_t1 = jnp.where(dip, t0 + fraction * (t1 - t0), next_t1)
        state = jax.tree.map(lambda new, old: jnp.where(dip, old, new), state, controller_state)
        return keep, next_t0, next_t1, made_jump, state, result


def constant(tree):
    """`tree` with no derivative flowing through its arrays: for what only chooses (a mode, a
    step, which guard fired), whose derivative is zero. Its tangents, computed and then
    dropped, made most of the work of differentiating a hybrid step's choices."""
    dynamic, static = eqx.partition(tree, eqx.is_inexact_array)
    return eqx.combine(jax.lax.stop_gradient(dynamic), static)


def batched_as(tree, like):
    """`tree`, its values unchanged, but batched under `jax.vmap` wherever a float array of `like` is.

    A loop carry that enters a vmapped `lax.scan` unbatched and leaves its body batched (a
    count, a flag, the time reached; a state from one start, stepped with batched parameters)
    makes JAX batch the whole body once more for each such change of the carry's batching.
    Started batched wherever what the body reads is, the body is batched once.
    """
    floats = [x for x in jax.tree.leaves(like) if eqx.is_inexact_array(x) and x.size]
    if not floats:
        return tree
    # Any predicate read off them will do: both branches are the value itself.
    read = functools.reduce(jnp.logical_or, [jnp.isnan(jnp.ravel(x)[0]) for x in floats])
    return jax.tree.map(lambda x: jnp.where(read, x, x), tree)


def varying_zero(y: Array) -> Scalar:
    """Zero, in `y`'s dtype, that varies as `y` does under `jax.vmap` and in `jax.jvp`: batched
    where `y` is, with a (zero) tangent where `y` has one.

    A loop carry started at it (the time reached, the time of a first event) enters the loop
    as the body will leave it, so that JAX traces the body's derivative once, not again when
    its first pass finds that carry entry differentiated.
    """
    a = jnp.ravel(y)[0]
    # `a - a` is exactly zero for a finite `a`, and so is its derivative, `da - da`.
    return jnp.where(jnp.isfinite(a), a - a, jnp.zeros_like(a))


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

    def terminate(self, fn, y, args, options, state, tags):
        del fn, args, options, tags
        scale = self.atol + self.rtol * jnp.abs(y)
        return jnp.abs(state.lower - state.upper) < scale, optimistix.RESULTS.successful


class SegmentEnd(NamedTuple):
    """Where a segment ended: its state and time (the inputs, for an env already at `dt`), the
    solve's result, whether it succeeded (an event ends a segment successfully), its
    accepted and attempted steps (0 for an env already at `dt`)."""

    y: State
    t: Scalar
    result: diffrax.RESULTS
    solved: BoolScalar
    accepted: IntScalar
    tried: IntScalar


def segment_solver(
    integrator: Integrator,
    vector_field: Callable,
    velocity_indices: tuple[int, ...] | None,
    condition: Callable,
    guard: Callable,
    dt: Scalar,
    *,
    root_finder: type[optimistix.Bisection] = optimistix.Bisection,
) -> Callable[[State, Scalar, Any], SegmentEnd]:
    """`solve(y, t, args)`: the solve from `(t, y)` towards `dt` that stops at the first zero of
    `condition`, located by bisection to a few machine epsilons in time, falling only.

    An adaptive step of the integrator's `PIDController` is also checked by `guard`
    (`GrazingGuardController`), so that a short dip of a condition within a step is located.
    """
    adjoint = integrator.adjoint
    if isinstance(adjoint, diffrax.BacksolveAdjoint):
        raise ValueError(
            "adjoint BacksolveAdjoint cannot differentiate through located events (diffrax refuses "
            "events with it): use with_adjoint(env, 'checkpoint') (reverse mode) or 'forward' (jacfwd)"
        )
    if type(adjoint) is diffrax.RecursiveCheckpointAdjoint and integrator.max_steps == 1:
        # A segment of one solver step (a constant-step preset): reverse mode through that step
        # as JAX differentiates any function (`DirectAdjoint`'s loop of one step is the step),
        # not through the checkpointed loop's machinery, which searches for what its body
        # perturbs by tracing it again and again. The same values and derivatives; about a
        # third less to trace and compile. Forward mode passes it too.
        adjoint = diffrax.DirectAdjoint()
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
        )

    return solve


class Settled(NamedTuple):
    """What `AbstractModes.settle` returns: the state and mode the next segment starts from,
    the events applied (one count per kind of `AbstractModes.kinds`), and the system's own
    checks of the mode it chose (name -> passed, the names `AbstractModes.checks`; a failed one
    fails the step)."""

    y: State
    mode: Any
    events: tuple[IntScalar, ...]
    checks: dict[str, BoolScalar]


class AbstractModes(eqx.Module):
    """A hybrid system as `integrate_hybrid` integrates it: modes, guards and resets.

    A mode is any PyTree of arrays (which contacts are closed, stick or slip, the sign of a
    normal force, what a Zeno check remembers). Within a mode the state follows
    `vector_field(t, y, (u, mode))`, and every entry of `guards(t, y, (u, mode))` is positive;
    a segment ends at the first located zero of their minimum. At each segment's start,
    `settle` applies the reset of the guard that fired (an impact map, a mode switch), or
    reads the mode off the state at a step's start (no guard fired). Impacts, friction
    switches and heel strikes are kinds of guard and reset; a scene that has several of
    them is one `AbstractModes` whose guards are theirs together (`ContactsWithFriction`).
    """

    kinds: eqx.AbstractClassVar[tuple[str, ...]]
    # The names of the checks `settle` returns (`Settled.checks`), each an entry of the info.
    checks: ClassVar[tuple[str, ...]] = ()
    root_finder: ClassVar[type[optimistix.Bisection]] = TimeBisection

    @property
    @abc.abstractmethod
    def max_events(self) -> int:
        """At most this many located events in one env step."""

    @abc.abstractmethod
    def initial_mode(self, y: State) -> Any:
        """A mode of the right structure, before the step's first `settle` reads the state."""

    @abc.abstractmethod
    def vector_field(self, t: ScalarLike, y: State, args) -> State: ...

    @abc.abstractmethod
    def guards(self, t: ScalarLike, y: State, args) -> Float[Array, " k"]:
        """Positive within the mode; the first to fall through zero ends the segment."""

    @abc.abstractmethod
    def settle(self, t: ScalarLike, y: State, u: Input, mode, fired: Bool[Array, " k"]) -> Settled:
        """The state and mode after the guard `fired` (all False at a step's start)."""

    def condition(self, t, y: State, args, **kwargs) -> ScalarLike:
        """The event's condition: the smallest guard, whose zero is the first of all of them; in the
        default float dtype, as diffrax 0.7.2's `cond` pairs it with `0.0` (float64 under x64)."""
        del kwargs
        guards = self.guards(t, y, args)
        return guards[jnp.argmin(guards)].astype(jnp.result_type(float))

    def dip(self, t0, t1, y0: State, y1: State, args) -> ScalarLike:
        """The step fraction where a guard's Hermite interpolant dips below zero and back (1 if none).

        A guard positive at both ends of a trial step is no event to diffrax, however far it
        fell between (a short lift-off, a load that touches its limit and falls back):
        `GrazingGuardController` rejects such a step and retries it up to the dip, where the
        sign change shows. The guards and their rates along the flow at both ends give the
        cubic Hermite interpolant. Just after a reset a guard starts at zero, or a rounding
        error below: if it rises and falls back below zero within the step (a hop shorter
        than a step) no sign change shows either, and the step is retried up to its peak.
        """
        step = t1 - t0

        def rates(t, y):
            t = jnp.asarray(t, y.dtype)
            return jax.jvp(lambda t, y: self.guards(t, y, args), (t, y), (jnp.ones_like(t), self.vector_field(t, y, args)))

        (c0, rate0), (c1, rate1) = rates(t0, y0), rates(t1, y1)
        s, lowest = hermite_dip(c0, c1, step * rate0, step * rate1)
        hidden = (c0 > 0) & (c1 > 0) & (rate0 < 0) & (rate1 > 0) & (lowest < 0)
        peak_at, negated_peak = hermite_dip(-c0, -c1, -step * rate0, -step * rate1)
        returned = (c0 <= 0) & (c1 < 0) & (rate0 > 0) & (rate1 < 0) & (negated_peak < 0)
        fraction = jnp.where(hidden, jnp.clip(s, 1e-3, 0.999), jnp.where(returned, jnp.clip(peak_at, 1e-3, 0.999), 1.0))
        # A choice of step, as the controller's own: no gradient flows through it.
        return jax.lax.stop_gradient(jnp.min(fraction))


def integrate_hybrid(
    integrator: Integrator,
    modes: AbstractModes,
    y0: State,
    u: Input,
    dt: ScalarLike,
    *,
    velocity_indices: tuple[int, ...] | None = None,
    projection: Callable[[State], State] | None = None,
) -> tuple[State, dict[str, Array]]:
    """Solve `modes` over `[0, dt]` from `y0` with the input `u` held: the one hybrid loop.

    Segment by segment, at most `modes.max_events + 1`: settle (the reset of the guard that
    fired, or the mode read off the state), then solve in that mode up to the first located
    zero of a guard (`segment_solver`). Which guard fired is the one at zero where the event
    was located: the minimum of the guards is the condition, so the event is the earliest
    crossing of any of them. (A `diffrax.Event` given the guards as a tuple reports, of those
    that changed sign within one solver step, the first in the tuple, not the first in time,
    and locates that one: two guards crossing within one step of a fixed-step solver would
    be taken in the wrong order and the earlier switch lost.) An event at the step's very
    end is settled before the step returns, so that the next step reads an exact state.

    The info holds `solver_ok` (every segment solved, `dt` reached within the segments, every
    check of `settle` passed, all finite), `solver_steps`, `solver_rejected_steps` (summed
    over segments), for each kind of event (`modes.kinds`, say "impact") the number applied,
    `impacts`, and the time of the first, `first_impact_time` (`inf` when none), and each of
    the modes' checks by name.
    """
    dt = jnp.asarray(dt, y0.dtype)
    solve = segment_solver(
        integrator, modes.vector_field, velocity_indices, modes.condition, modes.dip, dt, root_finder=modes.root_finder
    )
    no_event = jnp.zeros(jax.eval_shape(lambda y: modes.guards(0.0, y, (u, modes.initial_mode(y))), y0).shape, bool)

    def segment(carry, last):
        y, t, mode, fired, ok, checks, steps, rejected, counts, firsts = carry
        done = t >= dt
        # A segment starts by settling: the reset of the guard that fired, or the mode read off
        # the state. An event located at the very end of the step (or at the end of the last
        # segment) is settled too, by the next iteration, whose solve is then dropped: one
        # settle in the program, not a second one after the loop.
        settling = (~done & ~last) | jnp.any(fired)
        settled = modes.settle(t, y, u, mode, fired)
        if set(settled.checks) != set(modes.checks):
            raise TypeError(
                f"{type(modes).__name__}.settle returned the checks {sorted(settled.checks)}, "
                f"and its class declares checks = {modes.checks!r}"
            )
        y = jnp.where(settling, settled.y, y)
        mode = jax.tree.map(lambda new, old: jnp.where(settling, new, old), settled.mode, mode)
        events = tuple(jnp.where(settling, count, 0) for count in settled.events)
        idle = done | last
        end = solve(y, jnp.where(idle, dt, t), (u, mode))
        event = (end.result == diffrax.RESULTS.event_occurred) & ~idle
        fired = event & (jnp.arange(no_event.shape[0]) == jnp.argmin(constant(modes).guards(*constant((end.t, end.y, (u, mode))))))
        return (
            end.y,
            jnp.where(idle, t, end.t),
            mode,
            fired,
            ok & (idle | end.solved),
            # (The checks of a segment's start: a settle at the end applies its reset only.)
            {name: checks[name] & (idle | passed) for name, passed in settled.checks.items()},
            steps + end.accepted,
            rejected + end.tried - end.accepted,
            tuple(count + new for count, new in zip(counts, events)),
            tuple(jnp.where((new > 0) & (first == jnp.inf), t, first) for first, new in zip(firsts, events)),
        )

    def skip_done(carry, last):
        # The segments after every env's last one are skipped whole (`unvmap_any`: over a batch).
        pending = eqxi.unvmap_any((carry[1] < dt) | jnp.any(carry[3]))
        return jax.lax.cond(pending, checkpointed, lambda carry, last: carry, carry, last), None

    # Reverse mode keeps each segment's start only and recomputes the segment on the way back:
    # otherwise it stores the internals (solver checkpoints, event search) of all
    # `max_events + 2` segments, used or not. Values and gradients are unchanged.
    checkpointed = jax.checkpoint(segment, prevent_cse=False)
    # The time reached and the first events' times vary with the start from the first segment on.
    start = varying_zero(y0)
    zero, never = jnp.zeros((), int), start + jnp.inf
    mode = modes.initial_mode(y0)
    checks = {name: jnp.asarray(True) for name in modes.checks}
    kinds = range(len(modes.kinds))
    # Batched from the start under `vmap`, as a segment leaves it: over envs (the vmapped programs
    # of benchmarks/contact_compile.py, walls, Euler: 9% fewer Python calls to trace the gradient,
    # 36% fewer the loss alone) and over parameters from one start (the walled cart-pole's pole
    # mass: 4% and 34%; with friction and Tsit5, the gradient 8%). The same values and
    # gradients, bit for bit.
    initial = batched_as((
        y0, start, mode, no_event, jnp.asarray(True), checks, zero, zero,
        tuple(zero for _ in kinds), tuple(never for _ in kinds),
    ), (y0, u, modes))
    # `max_events + 1` segments, and one more that only settles an event that ended the last.
    lasts = jnp.arange(modes.max_events + 2) == modes.max_events + 1
    final, _ = jax.lax.scan(skip_done, initial, lasts)
    y, t, _, _, ok, checks, steps, rejected, counts, firsts = final  # no segment follows to read the mode
    finite = jnp.all(jnp.isfinite(y))
    if projection is not None:
        y = projection(y)
    ok = ok & (t >= dt) & finite & jnp.all(jnp.isfinite(y))
    for passed in checks.values():
        ok = ok & passed
    info = {"solver_ok": ok, "solver_steps": steps, "solver_rejected_steps": rejected, **checks}
    for kind, count, first in zip(modes.kinds, counts, firsts):
        plural = kind + ("es" if kind.endswith(("s", "sh", "ch", "x")) else "s")  # impacts, switches
        info |= {plural: count, f"first_{kind}_time": first}
    return y, info
