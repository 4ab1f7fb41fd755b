"""One env step of a disk on a floor with friction: flight, impacts with friction, stick and slip.

`integrate_on_floor` integrates over `[0, dt]` with the scene's `Integrator` segment by
segment (`lerax_like._segments`), each segment in one mode `(closed, s)`:

- open (`closed = 0`): free flight (`RollingDiskDynamics.vector_field`); its guard is the gap
  `z - radius`, falling through zero: an impact.
- closed and slipping in direction `s = +-1`: the floor holds `z = radius`, and the kinetic
  friction force `-mu_k N s` (`N = m g`) acts on the contact point; its guard is `s w`, the
  slip velocity `w = x_dot - radius angle_dot` reaching zero: the slip ends.
- closed and sticking (`s = 0`): rolling without slip, `x'' = radius angle''` exactly, with
  the friction force the torque needs (`holding_force`); the input is held over the step,
  so that force is constant and no guard falls within a segment.

Which guard ended a segment is read from the solve (`diffrax.Solution.event_mask`), not
recomputed. At the end of a segment, or at a step's start from the state:

- an impact (a located fall of the gap, or a state that starts touching, `z <= radius`,
  moving in): `DiskFloor.impact` (Newton's restitution, Coulomb's bound on the tangential
  impulse). A rebound slower than `min_rebound_speed` closes the contact (`z = radius`,
  `z_dot = 0` set exactly); otherwise the disk flies off.
- in contact: moving (`w != 0`) is slipping that way; at rest (`w = 0`, or a slip that
  ended) is sticking if `|holding_force| <= mu_s N`, else slipping in the direction the
  torque drives the contact point (a reversal through zero). Sticking sets `x_dot =
  radius angle_dot` exactly, so the stick is exact for any horizon (no creep, no chatter).

On a flat floor with only gravity vertical the normal force in contact is `m g > 0`: the
contact never opens by itself, and no slip is inconsistent (no Painleve case). A step that
needs more than `max_events` located events, or whose segment fails, reports
`info["solver_ok"] = False` (`lerax_like._segments.finish_step`), never a silent state.

Under `vmap` both branches of every `where` are computed: the impact map and every mode's
field are finite in every state (no division by a state-dependent quantity).

The info holds `solver_ok`, `solver_steps`, `solver_rejected_steps`, `impacts` and
`switches` (located in this step), `first_impact_time` and `first_switch_time` (`inf` when none).
"""

from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp

from ._segments import TimeBisection, finish_step, scan_segments, segment_solver
from ._types import Array, Input, ScalarLike, State
from .integrate import Integrator
from .physics.rolling_disk import DiskFloor, RollingDiskDynamics


class FloorModes(eqx.Module):
    """The disk's contact modes seen from the step: vector field, guards, and what follows an event.

    A mode is `(closed, s)`, floats: `closed` in {0, 1}, `s` in {-1, 0, 1} (0: sticking).
    """

    dynamics: RollingDiskDynamics
    floor: DiskFloor
    t0: ScalarLike = 0.0  # the episode's time at the step's start: the field reads `t0 + t`

    def vector_field(self, t, y: State, args) -> State:
        u, (closed, s) = args
        t = self.t0 + t
        flight = self.dynamics.vector_field(t, y, u)
        friction_force = -self.floor.kinetic_friction * self.dynamics.normal_force() * s
        sliding = self.dynamics.sliding_vector_field(t, y, u, friction_force)
        rolling = self.dynamics.rolling_vector_field(t, y, u)
        return jnp.where(closed == 0, flight, jnp.where(s == 0, rolling, sliding))

    def impact_guard(self, t, y: State, args, **kwargs):
        del t, kwargs
        _, (closed, _) = args
        return jnp.where(closed == 0, y[1] - self.dynamics.radius, jnp.ones_like(y[1]))

    def slip_guard(self, t, y: State, args, **kwargs):
        del t, kwargs
        _, (closed, s) = args
        return jnp.where((closed == 1) & (s != 0), s * self.dynamics.slip_velocity(y), jnp.ones_like(y[1]))

    def settle(self, y: State, u: Input, mode, ended: Array, impact_fired: Array, slip_fired: Array):
        """The next segment's state and mode, after the event that ended the last (`ended`), or
        read off the state at a step's start."""
        closed, s = mode
        radius = self.dynamics.radius
        touching = y[1] <= radius
        impact = jnp.where(ended, impact_fired, touching & (y[4] < 0))
        y = jnp.where(impact, self.floor.impact(self.dynamics, y), y)
        closes = impact & (y[4] < self.floor.min_rebound_speed)
        resting = jnp.where(ended, (closed == 1) & ~impact, touching & (y[4] == 0))
        now_closed = closes | resting
        y = jnp.where(closes, y.at[1].set(radius).at[4].set(0.0), y)
        holding = self.dynamics.holding_force(u)
        holds = jnp.abs(holding) <= self.floor.static_friction * self.dynamics.normal_force()
        away = -jnp.sign(holding)
        slip = self.dynamics.slip_velocity(y)
        # Rolling is `x_dot = radius angle_dot` to rounding: XLA may fuse the slip's product
        # and difference into one FMA, which leaves the exact residual of the rounded product.
        rounding = 8 * jnp.finfo(y.dtype).eps * jnp.maximum(jnp.abs(y[3]), jnp.abs(radius * y[5]))
        at_rest = (jnp.abs(slip) <= rounding) | (ended & slip_fired)
        new_s = jnp.where(at_rest, jnp.where(holds, 0.0, away), jnp.sign(slip))
        # A slip located to a few ulps of zero, or a state at rest, rolls exactly.
        y = jnp.where(now_closed & at_rest, y.at[3].set(radius * y[5]), y)
        new_mode = (now_closed.astype(y.dtype), jnp.where(now_closed, new_s, 0.0).astype(y.dtype))
        return y, new_mode


def integrate_on_floor(
    integrator: Integrator,
    dynamics: RollingDiskDynamics,
    floor: DiskFloor,
    y0: State,
    u: Input,
    dt: ScalarLike,
    *,
    projection: Callable[[State], State] | None = None,
    t0: ScalarLike = 0.0,
) -> tuple[State, dict[str, Array]]:
    """Solve over `[0, dt]` from `y0` with the floor's impacts and stick-slip switches located (module
    docstring); the vector field reads the episode's time `t0 + s`."""
    modes = FloorModes(dynamics=dynamics, floor=floor, t0=t0)
    dtype = y0.dtype
    dt = jnp.asarray(dt, dtype=dtype)
    no_dip = lambda t0, t1, y0, y1, args: jnp.ones((), dtype)  # flight's gap is concave, a slip's linear
    solve = segment_solver(
        integrator, modes.vector_field, dynamics.velocity_indices, (modes.impact_guard, modes.slip_guard),
        no_dip, dt, root_finder=TimeBisection,
    )

    def solve_segment(carry):
        y, t, mode, ended, fired, ok, steps, rejected, impacts, switches, first_impact, first_switch = carry
        done = t >= dt
        settled, new_mode = modes.settle(y, u, mode, ended, fired[0], fired[1])
        # After a closing impact at a step's end the next step reads the state; here it is settled.
        y = jnp.where(done, y, settled)
        mode = jax.tree.map(lambda new, old: jnp.where(done, old, new), new_mode, mode)
        end = solve(y, t, (u, mode))
        event = (end.result == diffrax.RESULTS.event_occurred) & ~done
        impact_fired, slip_fired = (event & mask for mask in end.fired)
        return (
            end.y,
            end.t,
            mode,
            event,
            (impact_fired, slip_fired),
            ok & (done | end.solved),
            steps + end.accepted,
            rejected + end.tried - end.accepted,
            impacts + impact_fired.astype(int),
            switches + slip_fired.astype(int),
            jnp.where(impact_fired & (first_impact == jnp.inf), end.t, first_impact),
            jnp.where(slip_fired & (first_switch == jnp.inf), end.t, first_switch),
        )

    zero = jnp.zeros((), dtype=int)
    false = jnp.asarray(False)
    never = jnp.asarray(jnp.inf, dtype)
    mode = (jnp.zeros((), dtype), jnp.zeros((), dtype))
    initial = (y0, jnp.zeros((), dtype), mode, false, (false, false), jnp.asarray(True), zero, zero, zero, zero, never, never)
    # Reverse mode keeps each segment's start only and recomputes the segment on the way back
    # (as `lerax_like.hybrid`): otherwise it stores the internals of all `max_events + 1` segments.
    final = scan_segments(jax.checkpoint(solve_segment, prevent_cse=False), initial, floor.max_events + 1, dt)
    y, t, mode, ended, fired, ok, steps, rejected, impacts, switches, first_impact, first_switch = final
    # An event at the step's very end is settled here, so that a closing impact or a stick
    # located at `dt` leaves an exact state for the next step to read.
    settled, _ = modes.settle(y, u, mode, ended, fired[0], fired[1])
    y = jnp.where(ended, settled, y)
    y, info = finish_step(y, t, ok, steps, rejected, dt, projection)
    return y, info | {
        "impacts": impacts, "switches": switches, "first_impact_time": first_impact, "first_switch_time": first_switch,
    }


__all__ = ["FloorModes", "integrate_on_floor"]
