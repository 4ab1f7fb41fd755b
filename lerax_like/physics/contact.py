"""Contact as an add-on: surfaces `g(y) >= 0` that the solver locates, and the map at an impact.

A physics module knows nothing of contact. What a scene adds on top, a floor, a wall, the
ends of a cart's rail, the next spoke of a rimless wheel, is a contact add-on: real-valued
conditions `g_i(y) >= 0` (the gaps; `g_i = 0` on surface `i`) and the map applied when the
state reaches one of them moving in. The step (`lerax_like.hybrid`) integrates segment by
segment, stops at the first located zero of a gap, applies the map and goes on; a scene
built without contacts carries and computes none of it.

`AbstractContact` takes any condition and any map (a heel strike that swaps the stance
leg, a switch of a non-mechanical mode); `AbstractImpulseContact` is the mechanical contact
of rigid bodies, whose map is the impulse-consistent one (`set_normal_speed`: a cart
hitting a wall changes its pole's angular velocity too), with rest below
`min_rebound_speed` (`resting_force`: the rule that ends a ball's Zeno sequence of bounces).

Gradients through an impact are the true derivatives of the hybrid flow, event time
included; near a grazing contact (normal speed `v_n -> 0`) they grow like `1 / v_n`:
the impact time `t*` moves by `-dg / v_n` when the trajectory moves by `dg`. That is the
physics of a trajectory that barely touches, not a numerical failure.
"""

import abc
from typing import Protocol, final, runtime_checkable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._fields import POSITIVE, AbstractParametrised, Range, option
from .._types import Array, Bool, Float, Scalar, ScalarLike, State
from ._base import AbstractChainDynamics, AbstractConservativeDynamics, AbstractDynamics, require_attributes

RESTITUTION = Range(
    "finite and in [0, 1] (allowed range [0, 1])",
    lambda a: bool(np.all(np.isfinite(a)) and np.all(a >= 0) and np.all(a <= 1)),
)


@runtime_checkable
class MechanicalDynamics(Protocol):
    """What an impulse contact reads off its dynamics: generalised coordinates and energy
    (`AbstractImpulseContact.check` refuses dynamics without them)."""

    def coordinates(self, y: State) -> tuple[Float[Array, " q"], Float[Array, " q"]]: ...

    def energy(self, y: State) -> Scalar: ...


class AbstractContact(AbstractParametrised):
    """Contact surfaces `g_i(y) >= 0` and the map applied at an impact on one of them.

    Subclasses implement `gaps` (one real value per surface: positive off the surface,
    zero on it, negative past it) and `impact` (the state just after an impact on one
    surface). `max_events` (static) bounds the impacts and releases located in one env
    step: a step that needs more is a failed step (`info["solver_ok"]` False), never
    silently cut short. The step checks `gaps` where a step of an adaptive solver could
    hide a touch and return (`lerax_like.hybrid`), from `gaps` and their rates.
    """

    max_events: int = option(16, None)

    @abc.abstractmethod
    def gaps(self, dynamics: AbstractDynamics, y: State) -> Float[Array, " k"]:
        """The gap to each surface in the state `y` (>= 0 admissible)."""

    @abc.abstractmethod
    def impact(self, dynamics: AbstractDynamics, y: State, surface: int) -> State:
        """The state just after an impact on `surface` (a Python int) in the state `y`."""

    def check(self, dynamics: AbstractDynamics) -> None:
        """Refuse, naming both, dynamics this contact cannot act on (nothing by default)."""
        del dynamics

    def __check_init__(self):
        if isinstance(self.max_events, bool) or not isinstance(self.max_events, (int, np.integer)) or self.max_events < 1:
            raise ValueError(f"max_events must be a positive integer, got {self.max_events!r}")


class AbstractImpulseContact(AbstractContact):
    """Rigid-body contact: an impulse-consistent velocity jump, and rest below a rebound speed.

    Subclasses implement `gaps` as functions of the positions `q` only (a surface of the
    configuration space) and declare `restitution` and `min_rebound_speed`. The dynamics
    must provide `coordinates(y) -> (q, q_dot)` (a selection of the state's components)
    and `energy(y)`, kinetic plus potential, the kinetic part `q_dot^T M(q) q_dot / 2`.
    """

    # equinox types `AbstractVar[T]` as `Annotated[T, ...]` for a type checker, which then takes it for
    # a field without a default after `max_events`; at run time it declares no field at all.
    restitution: eqx.AbstractVar[Scalar]  # pyright: ignore[reportGeneralTypeIssues]
    min_rebound_speed: eqx.AbstractVar[Scalar]  # pyright: ignore[reportGeneralTypeIssues]

    def check(self, dynamics: AbstractDynamics) -> None:
        require_attributes(self, dynamics, ("coordinates", "energy"), "generalised coordinates and energy, for the mass matrix")

    def impact(self, dynamics: AbstractDynamics, y: State, surface: int) -> State:
        """Reverse the normal velocity on `surface` times `restitution`, impulse-consistently.

        A rebound slower than `min_rebound_speed` is made zero (a plastic impact): the
        contact then rests (see `resting_force`).
        """
        normal_speed = self.normal_speeds(dynamics, y)[surface]
        rebound = -self.restitution * normal_speed
        rebound = jnp.where(jnp.abs(rebound) < self.min_rebound_speed, jnp.zeros_like(rebound), rebound)
        return self.set_normal_speed(dynamics, y, surface, rebound)

    # -- mechanics read off the dynamics --------------------------------------------------

    def jacobian(self, dynamics, y: State) -> Float[Array, "k q"]:
        """`J = dg/dq`, one row per surface."""
        q, _ = dynamics.coordinates(y)
        return jax.jacfwd(lambda p: self.gaps(dynamics, with_coordinates(dynamics, y, positions=p)))(q)

    def normal_speeds(self, dynamics, y: State) -> Float[Array, " k"]:
        """`J q_dot`: the rate of each gap (negative: moving into the surface)."""
        _, q_dot = dynamics.coordinates(y)
        return self.jacobian(dynamics, y) @ q_dot

    def set_normal_speed(self, dynamics, y: State, surface: int, speed: ScalarLike) -> State:
        """`y` with `J_i q_dot` set to `speed` by an impulse along `J_i^T`: `M dq_dot = J_i^T lambda`."""
        _, q_dot = dynamics.coordinates(y)
        row = self.jacobian(dynamics, y)[surface]
        direction = jnp.linalg.solve(mass_matrix(dynamics, y), row)  # M^-1 J^T
        impulse = (speed - row @ q_dot) / (row @ direction)
        return with_coordinates(dynamics, y, velocities=q_dot + impulse * direction)

    def resting_force(
        self, dynamics, y: State, acceleration: Float[Array, " q"], resting: Bool[Array, " k"]
    ) -> tuple[Float[Array, " k"], Float[Array, " q"]]:
        """The contact forces `lambda` that hold the `resting` surfaces (others: 0), and `M^-1 J^T lambda`.

        With `acceleration` the free `q''`, they make `d2g_i/dt2 = J_i q'' + q_dot^T H_i q_dot`
        zero for every resting surface `i` (`H_i` the Hessian of `g_i`): a surface
        pushes (`lambda_i > 0`) for as long as it holds.
        """
        q, q_dot = dynamics.coordinates(y)
        jacobian = self.jacobian(dynamics, y)
        gaps_of = lambda p: self.gaps(dynamics, with_coordinates(dynamics, y, positions=p))
        curvature = jax.jvp(lambda p: jax.jacfwd(gaps_of)(p) @ q_dot, (q,), (q_dot,))[1]
        masked = jnp.where(resting[:, None], jacobian, 0.0)
        inverse_mass_jacobian = jnp.linalg.solve(mass_matrix(dynamics, y), masked.T)  # (q, k)
        # Free surfaces get a unit diagonal, so that the system stays regular and their force is 0.
        delassus = masked @ inverse_mass_jacobian + jnp.diag(jnp.where(resting, 0.0, 1.0).astype(y.dtype))
        force = jnp.linalg.solve(delassus, -jnp.where(resting, jacobian @ acceleration + curvature, 0.0))
        return force, inverse_mass_jacobian @ force


def with_coordinates(dynamics, y: State, *, positions=None, velocities=None) -> State:
    """`y` with its generalised positions and/or velocities replaced, whatever the state's layout.

    `coordinates` selects components of `y`, a linear map whose transpose puts them back.
    """
    q, q_dot = dynamics.coordinates(y)
    change = (jnp.zeros_like(q) if positions is None else positions - q,
              jnp.zeros_like(q_dot) if velocities is None else velocities - q_dot)
    (back,) = jax.linear_transpose(dynamics.coordinates, y)(change)
    return y + back


def _closed_form(dynamics) -> bool:
    return isinstance(dynamics, AbstractConservativeDynamics) and callable(getattr(dynamics, "mass_matrix", None))


def mass_matrix(dynamics, y: State) -> Float[Array, "q q"]:
    """`M(q)`: the Hessian of the energy in the generalised velocities (the potential has none).

    Conservative dynamics that give their own closed form (`mass_matrix(y)`: the cart-pole,
    the chains of `lerax_like.physics.chain`, the ball, the sliding block) are read from it:
    the same matrix (tests/test_contact.py), and a gradient program through located contacts
    no longer traces and compiles a Hessian of the energy, differentiated again, at every
    evaluation of a guard.
    """
    if _closed_form(dynamics):
        return dynamics.mass_matrix(y)
    _, q_dot = dynamics.coordinates(y)
    return jax.hessian(lambda v: dynamics.energy(with_coordinates(dynamics, y, velocities=v)))(q_dot)


@final
class Walls(AbstractImpulseContact):
    """Rigid walls at the ends of a cart's rail, `x = -track_limit` and `x = +track_limit`.

    The cart rebounds with `restitution` `e` times its normal speed, impulse-consistently
    with the whole chain's mass matrix: a pole's angular velocity jumps too. Below
    `min_rebound_speed` (m/s) the cart comes to rest against the wall until the wall's
    force would pull. The located alternative to the penalty `EndStops`.
    """

    restitution: Scalar = eqx.field(converter=RESTITUTION, kw_only=True)
    track_limit: Scalar = eqx.field(default=2.4, converter=POSITIVE)
    min_rebound_speed: Scalar = eqx.field(default=1e-3, converter=POSITIVE)

    def gaps(self, dynamics: AbstractChainDynamics, y: State) -> Float[Array, " 2"]:
        x = dynamics.coordinates(y)[0][0]
        return jnp.stack([x + self.track_limit, self.track_limit - x])

    def check(self, dynamics: AbstractDynamics) -> None:
        super().check(dynamics)
        if not getattr(dynamics, "has_cart", False):
            raise ValueError(f"Walls stop a cart's position, and {type(dynamics).__name__} has no cart")


__all__ = [
    "RESTITUTION",
    "AbstractContact",
    "AbstractImpulseContact",
    "MechanicalDynamics",
    "Walls",
    "mass_matrix",
    "with_coordinates",
]
