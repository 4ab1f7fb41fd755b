"""One env step of a scene with contacts: integrate segment by segment, impacts located as events.

`Surfaces` is a scene's contacts (`lerax_like.physics.contact`) as a hybrid system of the one
loop (`lerax_like._segments.integrate_hybrid`): it integrates over `[0, dt]` with the scene's
`Integrator` (its solver, step-size controller, step budget and adjoint) up to the first
located zero of a contact's gap (a `diffrax.Event` with a real-valued condition, located by
bisection), applies the contact's map there and goes on from that time, until `dt`.
`AbstractEnv.evolve` integrates it when the scene has contacts. Every trap of a hybrid solve
is handled here:

- A state just after an impact sits on the surface (gap about 0, either sign): diffrax's sign
  test would miss a return within one step (a cart pressed into a wall by its controller ended
  2.9 m past it). So before every segment the state is checked for contact (touching, and
  moving in: an impact, whatever happened before), and the positions are re-placed just off
  the surface (a gap of 64 machine epsilons, scaled by the coordinates) so that the next
  crossing is a clean sign change.
- An adaptive step longer than a short touch steps over it (a sign change and back within one
  step). Under a `PIDController` each trial step is checked: from the gaps and their rates at
  both ends, the cubic Hermite interpolant of each gap; a step over which it dips below zero is
  rejected and retried up to the dip's lowest point, where the crossing shows. Constant-step
  solvers take the steps they are given: choose `substeps` small enough for the motion.
- Located by `optimistix.Bisection` at a tolerance of a few machine epsilons in time, with a
  fixed direction (`flip=True`: the gap decreases through the event). Newton, started from the
  step's end, heads for a root outside the step near a grazing contact and fails; a looser
  tolerance (1e-12) makes parameter gradients noisy at 1e-4.
- Coming to rest (a Zeno sequence of ever shorter bounces) ends by the contact's rule
  (`AbstractImpulseContact.min_rebound_speed`): a slower rebound is plastic and the surface
  becomes a constraint, whose force is computed from the dynamics; the constraint is released
  by a located event when that force reaches zero.
- At most `max_events` impacts and releases per env step (the contacts' largest). A step
  that needs more, a segment that fails, or a root that cannot be located, is a failed step
  (`info["solver_ok"]` False; the env keeps the pre-step state and pays the worst reward).

Gradients: the event time is differentiated implicitly (diffrax), so a gradient through an
impact is the derivative of the hybrid flow, the saltation correction included. It grows like
`1 / v_n` near a grazing contact (normal speed `v_n -> 0`): true, not a bug. Reverse mode
(`RecursiveCheckpointAdjoint`, the default) and forward mode (`ForwardMode`, for `jax.jacfwd`)
work; `BacksolveAdjoint` cannot pass events and is refused by name.

The info holds `solver_ok`, `solver_steps`, `solver_rejected_steps` (summed over segments),
`impacts` (impacts applied in this step) and `first_impact_time` (time of the first one
within the step, `inf` when none).
"""

from typing import ClassVar, final

import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import optimistix

from ._segments import AbstractModes, Settled, constant, hermite_dip
from ._types import Array, Bool, Float, Input, Scalar, ScalarLike, State
from .physics import AbstractDynamics
from .physics.contact import AbstractContact, AbstractImpulseContact, MechanicalDynamics, with_coordinates


# A surface touched again within this share of `dt` of the segment start where it was last
# touched has come to rest: the bounces of a Zeno sequence are shorter than the step can
# resolve. A fixed-step solver reaches it where the speed rule cannot: semi-implicit Euler
# pushed into a wall (restitution e, push a, step h) settles on impacts at h a / (1 + e), not on
# ever slower ones; and its dense output, which blends the velocities while the positions move
# with the new ones, can place a crossing at a state moving away from the wall (no impact), the
# next step crossing again at once.
ZENO_FRACTION = 2.0**-30


@final
class Surfaces(AbstractModes):
    """The scene's contacts seen as one list of surfaces: gaps, rates, maps, rest.

    Its mode is `(resting, touched, touched_at)`: which surfaces rest (a constraint whose
    force is computed from the dynamics), and which were touched at the last segment start
    that touched any, and when (the Zeno check, `ZENO_FRACTION`). Times `t` are the solve's,
    from the env step's start; the physics is read at the episode's time `t0 + t`, as
    `Integrator.integrate` reads it (`EpisodeTime`). `physics` is what is integrated (the
    dynamics with any force add-ons); `dynamics` the scene's own physics module, whose
    `coordinates` and `energy` the contacts read.
    """

    kinds: ClassVar[tuple[str, ...]] = ("impact",)
    # Gaps are located to a few machine epsilons in value as well as in time.
    root_finder: ClassVar[type[optimistix.Bisection]] = optimistix.Bisection

    physics: AbstractDynamics
    dynamics: AbstractDynamics
    contacts: tuple[AbstractContact, ...]
    dt: Scalar
    t0: ScalarLike = 0.0

    @property
    def max_events(self) -> int:
        """Impacts and releases in one env step: the contacts' largest `max_events`."""
        return max(contact.max_events for contact in self.contacts)

    def initial_mode(self, y: State):
        free = jnp.zeros_like(self.gaps(y), dtype=bool)
        return free, free, jnp.asarray(-jnp.inf, y.dtype)

    def gaps(self, y: State) -> Float[Array, " k"]:
        return jnp.concatenate([contact.gaps(self.dynamics, y) for contact in self.contacts])

    def sizes(self, y: State) -> list[int]:
        return [jax.eval_shape(lambda z: contact.gaps(self.dynamics, z), y).shape[0] for contact in self.contacts]

    def vector_field(self, t: ScalarLike, y: State, args) -> State:
        """The physics, with the resting surfaces' constraint forces added."""
        u, (resting, _, _) = args
        derivative = self.physics.vector_field(self.t0 + t, y, u)
        # `unvmap_any`: true if any env of a vmapped batch rests, so that a batch in which
        # none does skips the constraint (a `cond` on a batched predicate runs both branches).
        return jax.lax.cond(
            eqxi.unvmap_any(jnp.any(resting)), lambda y, d, r: self._constrained(y, d, r), lambda y, d, r: d, y, derivative, resting
        )

    def _constrained(self, y: State, derivative: State, resting) -> State:
        start = 0
        for contact, size in zip(self.contacts, self.sizes(y)):
            if isinstance(contact, AbstractImpulseContact):
                mask = resting[start : start + size]
                _, acceleration = self.mechanics.coordinates(derivative)
                _, change = contact.resting_force(self.dynamics, y, acceleration, mask)
                derivative = with_coordinates(self.dynamics, derivative, velocities=acceleration + change)
            start += size
        return derivative

    def forces(self, t, y: State, u: Input, resting: Bool[Array, " k"]) -> Float[Array, " k"]:
        """The resting surfaces' contact forces (0 for the others)."""
        return jax.lax.cond(
            eqxi.unvmap_any(jnp.any(resting)), lambda t, y, u, r: self._forces(t, y, u, r),
            lambda t, y, u, r: jnp.zeros_like(r, dtype=y.dtype), t, y, u, resting,
        )

    def _forces(self, t, y: State, u: Input, resting: Bool[Array, " k"]) -> Float[Array, " k"]:
        derivative = self.physics.vector_field(self.t0 + t, y, u)
        forces, start = [], 0
        for contact, size in zip(self.contacts, self.sizes(y)):
            if isinstance(contact, AbstractImpulseContact):
                # Read here, not before the loop: a scene's own contact (a rimless wheel's
                # spokes) needs no generalised coordinates of its dynamics.
                _, acceleration = self.mechanics.coordinates(derivative)
                force, _ = contact.resting_force(self.dynamics, y, acceleration, resting[start : start + size])
            else:
                force = jnp.zeros((size,), y.dtype)
            forces.append(force)
            start += size
        return jnp.concatenate(forces)

    def rates(self, t, y: State, args) -> tuple[Float[Array, " k"], Float[Array, " k"]]:
        """The gaps and their time derivatives along the flow."""
        return jax.jvp(self.gaps, (y,), (self.vector_field(t, y, args),))

    def guards(self, t, y: State, args) -> Float[Array, " k"]:
        """Positive between events: the free surfaces' gaps and the resting ones' forces."""
        u, (resting, _, _) = args
        return jnp.where(resting, self.forces(t, y, u, resting), self.gaps(y))

    def dip(self, t0, t1, y0: State, y1: State, args):
        """The step fraction where a free gap's Hermite interpolant dips below zero (1 if none)."""
        _, (resting, _, _) = args
        step = t1 - t0
        g0, rate0 = self.rates(t0, y0, args)
        g1, rate1 = self.rates(t1, y1, args)
        s, lowest = hermite_dip(g0, g1, step * rate0, step * rate1)
        hidden = ~resting & (g0 > 0) & (g1 > 0) & (rate0 < 0) & (rate1 > 0) & (lowest < 0)
        # The retried step ends at the dip's lowest point, a little past it if the lowest
        # point sits at an end, so that it shrinks.
        fraction = jnp.where(hidden, jnp.clip(s, 1e-3, 0.999), 1.0)
        # A choice of step, as the controller's own: no gradient flows through it.
        return jax.lax.stop_gradient(jnp.min(fraction))

    def offset(self, y: State):
        """How far off a surface a state is re-placed: 64 machine epsilons, scaled by the coordinates."""
        q, _ = self.mechanics.coordinates(y) if self._mechanical else (y, None)
        return 64 * jnp.finfo(y.dtype).eps * (1 + jnp.max(jnp.abs(q)))

    def settle(self, t, y: State, u: Input, mode, fired) -> Settled:
        """At a segment's start `t`: impacts, rest and release, and the re-placement just off the
        surfaces, read off the state whatever fired (`touch`); counts the impacts."""
        del fired
        _, touched, touched_at = mode
        again = touched & (t - touched_at <= ZENO_FRACTION * self.dt)
        y, resting, hit, touching = self.touch(t, y, u, again)
        touched_at = jnp.where(jnp.any(touching), t, touched_at)
        touched = jnp.where(jnp.any(touching), touching, touched)
        return Settled(y, (resting, touched, touched_at), (jnp.sum(hit, dtype=int),), {})

    def touch(self, t, y: State, u: Input, again: Bool[Array, " k"]):
        """At a segment's start `t`: impacts, rest and release, and the re-placement just off the surfaces.

        `again` marks the surfaces touched at a segment start within `ZENO_FRACTION` of `dt`
        before: touched again, they come to rest instead of bouncing. Returns the state, the
        resting surfaces, the surfaces struck and the surfaces touched. All of it is skipped
        when no state (of a vmapped batch) touches a surface.
        """
        # Whether a surface is touched is a choice (`constant`), as are `_settle`'s impacts and rest.
        touching = constant(self).gaps(constant(y)) <= 2 * constant(self).offset(constant(y))
        return jax.lax.cond(
            eqxi.unvmap_any(jnp.any(touching)),
            lambda t, y, u, again: self._settle(t, y, u, again),
            lambda t, y, u, again: (y, jnp.zeros_like(touching), jnp.zeros_like(touching), touching),
            t, y, u, again,
        )

    def _settle(self, t, y: State, u: Input, again: Bool[Array, " k"]):
        offset = self.offset(y)
        start = 0
        sizes = self.sizes(y)
        touching_all, hits_all, candidates_all = [], [], []
        for contact, size in zip(self.contacts, sizes):
            for local in range(size):
                choosing, fixed = constant((self, contact)), constant((t, y, u, offset))
                gap = choosing[1].gaps(choosing[0].dynamics, fixed[1])[local]
                rate = jax.jvp(
                    lambda z: choosing[1].gaps(choosing[0].dynamics, z)[local], (fixed[1],),
                    (choosing[0].physics.vector_field(choosing[0].t0 + fixed[0], fixed[1], fixed[2]),),
                )[1]
                touching = gap <= 2 * fixed[3]
                hit = touching & (rate < 0) & ~again[start + local]
                y = jnp.where(hit, contact.impact(self.dynamics, y, local), y)
                touching_all.append(touching)
                hits_all.append(hit)
            start += size
        touching = jnp.stack(touching_all)
        # Rest: touching surfaces of impulse contacts whose normal speed is below the rebound
        # threshold, held there if their force pushes.
        start = 0
        for contact, size in zip(self.contacts, sizes):
            if isinstance(contact, AbstractImpulseContact):
                speeds = constant(contact).normal_speeds(constant(self.dynamics), constant(y))
                for local in range(size):
                    slow = touching[start + local] & (
                        (jnp.abs(speeds[local]) < contact.min_rebound_speed) | again[start + local]
                    )
                    candidates_all.append(slow)
                    y = jnp.where(slow, contact.set_normal_speed(self.dynamics, y, local, 0.0), y)
            else:
                candidates_all.extend([jnp.asarray(False)] * size)
            start += size
        candidates = jnp.stack(candidates_all)
        resting = candidates & (constant(self).forces(*constant((t, y, u)), candidates) > 0)
        # Re-place impulse contacts' touching surfaces just off them (a Newton step on the
        # positions along the gap's gradient: exact for flat surfaces).
        start = 0
        for contact, size in zip(self.contacts, sizes):
            if isinstance(contact, AbstractImpulseContact):
                for local in range(size):
                    gap = contact.gaps(self.dynamics, y)[local]
                    row = contact.jacobian(self.dynamics, y)[local]
                    q, _ = self.mechanics.coordinates(y)
                    moved = with_coordinates(self.dynamics, y, positions=q + (offset - gap) * row / (row @ row))
                    y = jnp.where(touching[start + local], moved, y)
            start += size
        return y, resting, jnp.stack(hits_all), touching

    @property
    def mechanics(self) -> MechanicalDynamics:
        """The dynamics as an impulse contact reads them: `coordinates` and `energy` (which
        its `check` required at construction)."""
        if not isinstance(self.dynamics, MechanicalDynamics):
            raise TypeError(f"{type(self.dynamics).__name__} has no generalised coordinates and energy")
        return self.dynamics

    @property
    def _mechanical(self) -> bool:
        return any(isinstance(contact, AbstractImpulseContact) for contact in self.contacts)


__all__ = ["Surfaces"]
