"""A scene with both located contacts and Coulomb friction: impacts and stick-slip switches as two
kinds of guard of one hybrid system, integrated by the one loop (`lerax_like._segments`).

A segment runs in one friction mode (`lerax_like.stick_slip.FrictionModes`) and ends at the first
located zero of any guard: the friction's (a slip that ends, a release, a normal force that
changes sign, an inconsistent slip) or a contact's gap (`lerax_like.hybrid`). At each segment's
start the contacts settle first (a state touching a surface and moving in is struck: the
impact map, then the re-placement just off the surface), and after an impact the friction mode
is read off the new state (moving: slipping that way; at rest: held if it can be).

Limits, reported and never silent: a rebound slower than `min_rebound_speed` would leave the
scene resting on a surface with friction acting, which this step does not model; the step then
fails (`info["solver_ok"]` False, `info["contacts_bounce"]` False). So do an inconsistent slip
(`info["friction_consistent"]`), a segment that fails, and a step needing more than the
friction's and the contacts' `max_events` together.
"""

from typing import ClassVar, final

import jax.numpy as jnp

from ._segments import AbstractModes, Settled
from ._types import Array, Bool, Float, Input, ScalarLike, State
from .hybrid import Surfaces
from .stick_slip import FrictionModes


@final
class ContactsWithFriction(AbstractModes):
    """Located contacts and a Coulomb friction add-on as one hybrid system: the friction's modes
    (`FrictionModes`) and its four guards, and the contacts' gaps (`Surfaces`) beside them.

    Its mode is `(contacts' mode, friction's mode)`. At a segment's start the contacts settle
    first, then the friction: after an impact its mode is read off the new state.
    """

    kinds: ClassVar[tuple[str, ...]] = ("impact", "switch")
    checks: ClassVar[tuple[str, ...]] = (*FrictionModes.checks, "contacts_bounce")

    surfaces: Surfaces
    friction: FrictionModes

    @property
    def max_events(self) -> int:
        return self.surfaces.max_events + self.friction.max_events

    def initial_mode(self, y: State):
        return self.surfaces.initial_mode(y), self.friction.initial_mode(y)

    def vector_field(self, t: ScalarLike, y: State, args) -> State:
        u, (_, mode) = args
        return self.friction.vector_field(t, y, (u, mode))

    def guards(self, t, y: State, args) -> Float[Array, " k"]:
        """The friction's four guards, then the contacts' gaps."""
        u, (_, mode) = args
        return jnp.concatenate([self.friction.guards(t, y, (u, mode)), self.surfaces.gaps(y)])

    def settle(self, t, y: State, u: Input, mode, fired: Bool[Array, " k"]) -> Settled:
        contacts_mode, friction_mode = mode
        contacts = self.surfaces.settle(t, y, u, contacts_mode, fired[4:])
        (hits,) = contacts.events
        friction = self.friction.settle(t, contacts.y, u, friction_mode, fired[:4] & (hits == 0))
        resting, _, _ = contacts.mode
        checks = {**friction.checks, "contacts_bounce": ~jnp.any(resting)}
        return Settled(friction.y, (contacts.mode, friction.mode), (hits, *friction.events), checks)


__all__ = ["ContactsWithFriction"]
