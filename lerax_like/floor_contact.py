"""One env step of a disk on a floor with friction: flight, impacts with friction, stick and slip.

`FloorModes` is the disk on its floor as a hybrid system of the one loop
(`lerax_like._segments.integrate_hybrid`), which integrates over `[0, dt]` with the scene's
`Integrator` segment by segment, each segment in one mode `(closed, s)`:

- open (`closed = 0`): free flight (`RollingDiskDynamics.vector_field`); its guard is the gap
  `z - radius`, falling through zero: an impact.
- closed and slipping in direction `s = +-1`: the floor holds `z = radius`, and the kinetic
  friction force `-mu_k N s` (`N = m g`) acts on the contact point; its guard is `s w`, the
  slip velocity `w = x_dot - radius angle_dot` reaching zero: the slip ends.
- closed and sticking (`s = 0`): rolling without slip, `x'' = radius angle''` exactly, with
  the friction force the torque needs (`holding_force`); the input is held over the step,
  so that force is constant and no guard falls within a segment.

At the end of a segment, after the guard that fired, or at a step's start from the state:

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
`info["solver_ok"] = False`, never a silent state.

Under `vmap` both branches of every `where` are computed: the impact map and every mode's
field are finite in every state (no division by a state-dependent quantity).

The info holds `solver_ok`, `solver_steps`, `solver_rejected_steps`, `impacts` and
`switches` (located in this step), `first_impact_time` and `first_switch_time` (`inf` when none).
"""

from typing import ClassVar, final

import jax.numpy as jnp

from ._segments import AbstractModes, Settled
from ._types import Array, Bool, Float, Input, ScalarLike, State
from .physics.rolling_disk import DiskFloor, RollingDiskDynamics


@final
class FloorModes(AbstractModes):
    """The disk's contact modes seen from the step: vector field, guards, and what follows an event.

    A mode is `(closed, s)`, floats: `closed` in {0, 1}, `s` in {-1, 0, 1} (0: sticking).
    """

    kinds: ClassVar[tuple[str, ...]] = ("impact", "switch")

    dynamics: RollingDiskDynamics
    floor: DiskFloor
    t0: ScalarLike = 0.0  # the episode's time at the step's start: the field reads `t0 + t`

    def initial_mode(self, y: State):
        return jnp.zeros((), y.dtype), jnp.zeros((), y.dtype)

    def vector_field(self, t, y: State, args) -> State:
        u, (closed, s) = args
        t = self.t0 + t
        flight = self.dynamics.vector_field(t, y, u)
        friction_force = -self.floor.kinetic_friction * self.dynamics.normal_force() * s
        sliding = self.dynamics.sliding_vector_field(t, y, u, friction_force)
        rolling = self.dynamics.rolling_vector_field(t, y, u)
        return jnp.where(closed == 0, flight, jnp.where(s == 0, rolling, sliding))

    def guards(self, t, y: State, args) -> Float[Array, " 2"]:
        """In flight the gap `z - radius` (an impact); slipping, the slip speed `s w` (the slip ends)."""
        del t
        _, (closed, s) = args
        one = jnp.ones_like(y[1])
        return jnp.stack([
            jnp.where(closed == 0, y[1] - self.dynamics.radius, one),
            jnp.where((closed == 1) & (s != 0), s * self.dynamics.slip_velocity(y), one),
        ])

    def settle(self, t, y: State, u: Input, mode, fired: Bool[Array, " 2"]) -> Settled:
        """The next segment's state and mode, after the guard that `fired`, or read off the
        state at a step's start."""
        del t
        closed, s = mode
        ended = jnp.any(fired)
        impact_fired, slip_fired = fired
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
        # Rolling is `x_dot = radius angle_dot` to an ulp or so per solver step (x_dot and angle_dot are
        # updated apart): Euler at 256 substeps ended a step 1e-13 off, once read as a slip against the
        # static friction that holds it (the disk skidded). A slip below sqrt(eps) of the speed is rest.
        rounding = jnp.sqrt(jnp.finfo(y.dtype).eps) * jnp.maximum(jnp.abs(y[3]), jnp.abs(radius * y[5]))
        at_rest = (jnp.abs(slip) <= rounding) | (ended & slip_fired)
        new_s = jnp.where(at_rest, jnp.where(holds, 0.0, away), jnp.sign(slip))
        # A slip located to a few ulps of zero, or a state at rest, rolls exactly.
        y = jnp.where(now_closed & at_rest, y.at[3].set(radius * y[5]), y)
        new_mode = (now_closed.astype(y.dtype), jnp.where(now_closed, new_s, 0.0).astype(y.dtype))
        return Settled(y, new_mode, (impact.astype(int), slip_fired.astype(int)), {})

    @property
    def max_events(self) -> int:
        return self.floor.max_events


__all__ = ["FloorModes"]
