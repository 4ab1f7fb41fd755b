"""One env step of a scene with Coulomb friction: stick and slip integrated as modes, switches located.

`FrictionModes` is the friction add-on (`lerax_like.physics.friction`) as a hybrid system of the
one loop (`lerax_like._segments.integrate_hybrid`), which integrates over `[0, dt]` with the
scene's `Integrator` segment by segment, each segment in one mode:

- mode `(s, sigma)`: `s = +1` or `-1` slipping in that direction, `s = 0` sticking; `sigma`
  the sign of the normal force `N`, which `|N|` follows (Florian's correction).
- slip: the friction force is `-mu_k sigma s N`, solved with `N` (affine in it); stick: the
  sliding coordinate's rate and acceleration are exactly zero, so a block at rest under a
  sub-threshold load stays at rest to the last bit for any horizon (no creep, no chatter).
- a segment ends at the first located zero of its guards (`diffrax.Event`, bisection as for
  impacts, `lerax_like.hybrid`): the slip speed `s q_k_dot` (slip ends), `sigma N` (the normal
  force changes sign), `mu_s |N| - |f|` (a stick's force reaches its limit: release), and
  `1 + mu_k sigma s dN/df` (slip becomes inconsistent, Painleve's case).
- the next segment's mode: after a slip ends, stick if the holding force is within
  `mu_s |N|`, else slip away in the direction of the load (a reversal through zero); after
  a release, slip in the direction of the load; after `N` changes sign, `sigma` flips. At
  a step's start the mode is read off the state (`q_k_dot == 0`: at rest, if it can hold).

With an adaptive controller, a trial step over which a condition dips below zero and back
(or rises from a switch and falls back) is rejected and retried up to the dip or the peak
(`AbstractModes.dip`, the impacts' `GrazingGuardController`), so a short lift-off is located.

Every condition is read where it starts at zero or above and rises after a switch, and
diffrax's falling-direction test (`direction=False`) never fires on such a start. A step
that needs more than `max_events` switches, a segment that fails, or an inconsistent slip
is a failed step (`info["solver_ok"]` False, `info["friction_consistent"]` says which),
never silently cut short. Gradients through a switch are those of the hybrid flow: the
switching time is differentiated implicitly (diffrax's root find).

Under `vmap` every branch is computed for every env, so every division here has a
denominator made safe where the branch is not taken ("double where"): a stick's `1 / w_kk`
(`w_kk`, the inverse mass on `q_k`, is positive) and a slip's `1 / (1 + mu_k sigma s dN/df)`.

The info holds `solver_ok`, `solver_steps`, `solver_rejected_steps`, `switches` (located in
this step), `first_switch_time` (`inf` when none) and `friction_consistent`.
"""

from typing import Any, ClassVar, NamedTuple, final

import jax
import jax.numpy as jnp

from ._segments import AbstractModes, Settled, constant
from ._types import Array, Bool, Float, Input, ScalarLike, State
from .physics import AbstractDynamics
from .physics.contact import with_coordinates
from .physics.friction import AbstractCoulombFriction


# Which guard ended a segment (its index in `FrictionModes.guards`).
SLIP_ENDS, NORMAL_FLIPS, RELEASE, INCONSISTENT = range(4)


class _Forces(NamedTuple):
    """The friction forces of both modes in one state, and what they are made of."""

    free: State  # the derivative without friction
    unit: State  # its change per newton of friction on `q_k`
    normal: Array  # `N` without friction
    hold: Array  # the force that holds `q_k_dot = 0` (stick)
    hold_normal: Array  # `N` under it
    slip: Array  # the kinetic friction force of the mode's slip
    slip_normal: Array  # `N` under it
    denominator: Array  # `1 + mu_k sigma s dN/df`: a slip is consistent where it is > 0


@final
class FrictionModes(AbstractModes):
    """The friction's modes seen from the step: forces, vector field, guards, switches.

    A mode is `(s, sigma)`, floats: `s` in {-1, 0, 1} (0: stick), `sigma` in {-1, 1}.
    `physics` is the dynamics with any force add-ons (`ForcedDynamics`), whose generalised
    force the friction adds to; `dynamics` the scene's own physics module.
    """

    kinds: ClassVar[tuple[str, ...]] = ("switch",)
    checks: ClassVar[tuple[str, ...]] = ("friction_consistent",)

    physics: AbstractDynamics
    # Duck-typed: an `AbstractDynamics` with `coordinates` and `forced_vector_field` (what
    # `AbstractCoulombFriction.check` asks for), a chain's or a sliding block's.
    dynamics: Any
    friction: AbstractCoulombFriction
    t0: ScalarLike = 0.0  # the episode's time at the step's start: the field reads `t0 + t`

    @property
    def max_events(self) -> int:
        return self.friction.max_events

    def initial_mode(self, y: State):
        return jnp.zeros((), y.dtype), jnp.ones((), y.dtype)

    def forces(self, t, y: State, u: Input, mode) -> _Forces:
        s, sigma = mode
        t = self.t0 + t
        k = self.friction.coordinate
        q, _ = self.dynamics.coordinates(y)
        # The other add-ons' generalised force (hinge damping), to which friction adds.
        others = getattr(self.physics, "generalised_force", lambda y: jnp.zeros_like(q))(y)
        unit_force = jnp.zeros_like(q).at[k].set(1.0)
        field = lambda f: self.dynamics.forced_vector_field(t, y, u, others + f * unit_force)
        free, unit = jax.jvp(field, (jnp.zeros((), y.dtype),), (jnp.ones((), y.dtype),))
        _, acceleration = self.dynamics.coordinates(free)
        _, per_force = self.dynamics.coordinates(unit)
        normal, normal_per_force = jax.jvp(
            lambda a: self.friction.normal_force(self.dynamics, y, a), (acceleration,), (per_force,)
        )
        inverse_mass = per_force[k]  # (M^-1)_kk, positive
        hold = -acceleration[k] / jnp.where(inverse_mass > 0, inverse_mass, 1.0)
        slope = self.friction.kinetic_friction * sigma * s
        denominator = 1 + slope * normal_per_force
        slip = -slope * normal / jnp.where(denominator > 0, denominator, 1.0)
        return _Forces(
            free, unit, normal, hold, normal + normal_per_force * hold, slip, normal + normal_per_force * slip, denominator
        )

    def vector_field(self, t: ScalarLike, y: State, args) -> State:
        u, mode = args
        forces = self.forces(t, y, u, mode)
        stick = mode[0] == 0
        derivative = forces.free + jnp.where(stick, forces.hold, forces.slip) * forces.unit
        # At rest the sliding coordinate's rate and acceleration are zero exactly, not to
        # round-off: a held block must not creep over 10^4 steps.
        k = self.friction.coordinate
        rates, accelerations = self.dynamics.coordinates(derivative)
        held = with_coordinates(
            self.dynamics, derivative, positions=rates.at[k].set(0.0), velocities=accelerations.at[k].set(0.0)
        )
        return jnp.where(stick, held, derivative)

    def guards(self, t, y: State, args) -> Float[Array, " 4"]:
        """Positive within the mode; the first to fall through zero ends the segment (`SLIP_ENDS`, ...)."""
        u, (s, sigma) = args
        forces = self.forces(t, y, u, (s, sigma))
        speed = self.dynamics.coordinates(y)[1][self.friction.coordinate]
        slipping = s != 0
        margin = self.friction.static_friction * jnp.abs(forces.hold_normal) - jnp.abs(forces.hold)
        one = jnp.ones((), y.dtype)
        return jnp.stack([
            jnp.where(slipping, s * speed, one),
            jnp.where(slipping, sigma * forces.slip_normal, one),
            jnp.where(slipping, one, margin),
            jnp.where(slipping, forces.denominator, one),
        ])

    def settle(self, t, y: State, u: Input, mode, fired: Bool[Array, " 4"]) -> Settled:
        """The next segment's state and mode, and whether its slip is consistent.

        After a segment that ended on the switch that `fired`, the switch's rule; at a step's
        start, the mode read off the state: moving is slipping that way, at rest is held if
        it can be, else slipping in the direction of the load.
        """
        ended = jnp.any(fired)
        s, sigma = mode
        k = self.friction.coordinate
        # The mode is a choice (`constant`): no derivative flows into the forces that choose it.
        forces = constant(self).forces(*constant((t, y, u, mode)))
        holds = jnp.abs(forces.hold) <= self.friction.static_friction * jnp.abs(forces.hold_normal)
        away = -jnp.sign(forces.hold)
        held_sign = jnp.where(forces.hold_normal >= 0, 1.0, -1.0).astype(y.dtype)
        # A consistent slip's normal force has the sign of the frictionless one.
        free_sign = jnp.where(forces.normal >= 0, 1.0, -1.0).astype(y.dtype)
        speed = self.dynamics.coordinates(y)[1][k]
        read_s = jnp.where(speed == 0, jnp.where(holds, 0.0, away), jnp.sign(speed))
        read_sigma = jnp.where(speed == 0, held_sign, free_sign)
        stops, released = fired[SLIP_ENDS], fired[RELEASE]
        new_s = jnp.where(stops, jnp.where(holds, 0.0, away), jnp.where(released, away, s))
        new_sigma = jnp.where(stops | released, held_sign, jnp.where(fired[NORMAL_FLIPS], -sigma, sigma))
        new_s = jnp.where(ended, new_s, read_s)
        new_sigma = jnp.where(ended, new_sigma, read_sigma)
        # A slip that ends stops the coordinate exactly (it was located to a few ulps of zero).
        _, rates = self.dynamics.coordinates(y)
        y = jnp.where(stops, with_coordinates(self.dynamics, y, velocities=rates.at[k].set(0.0)), y)
        # The new mode's slip must be consistent (Painleve), checked where it starts.
        denominator = constant(self).forces(*constant((t, y, u, (new_s, new_sigma)))).denominator
        consistent = ((new_s == 0) | (denominator > 0)) & ~fired[INCONSISTENT]
        return Settled(y, (new_s, new_sigma), (ended.astype(int),), {"friction_consistent": consistent})


__all__ = ["FrictionModes"]
