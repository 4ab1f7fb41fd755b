"""Passive walkers: a stance phase that ends at a heel strike, located as an event.

A walker's dynamics declares its `slope`, the gap `front_gap(y)` to its next heel strike
(positive during the step, zero when the swing foot lands) and the `heel_strike(y)` map
(the impact and the legs' exchange). That is all the step-to-step return map
(`lerax_like.analysis.gait`) and the `HeelStrike` contact (`lerax_like.hybrid`) read.
"""

import abc
from typing import final

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._fields import Range, option
from .._types import Array, Float, Scalar, State
from ._base import AbstractDynamics
from .contact import AbstractContact

SLOPE = Range(
    "in [0, pi/2) (allowed range [0, pi/2), radians downhill)",
    lambda a: bool(np.all(np.isfinite(a)) and np.all((a >= 0) & (a < np.pi / 2))),
)


class AbstractWalkerDynamics(AbstractDynamics):
    """Dynamics of a passive walker on a slope: a stance phase ended by a heel strike."""

    slope: eqx.AbstractVar[Scalar]

    @abc.abstractmethod
    def front_gap(self, y: State) -> Scalar:
        """Positive during a step, zero at the next heel strike (and decreasing through it)."""

    @abc.abstractmethod
    def heel_strike(self, y: State) -> State:
        """The state just after the swing foot lands in the state `y`: it is the new stance foot."""

    @abc.abstractmethod
    def stance_angle(self, y: State) -> Scalar:
        """The stance leg's angle from the slope's normal, positive with the hip downhill of the foot."""

    @abc.abstractmethod
    def hip_speed(self, y: State) -> Scalar:
        """The hip's velocity along the slope, positive downhill."""


def swing_gap(stance: Scalar, gap: Scalar, gap_rate: Scalar) -> Scalar:
    """The heel strike's gap of a two-legged walker, blind to the swing foot's scuffing at mid-stance.

    `gap` is zero on both configurations where the swing foot touches the slope with the
    legs spread symmetrically about the slope's normal: twice a step, since a rigid swing
    leg passes under the slope at mid-stance (the scuffing the models ignore), and at the
    heel strike; also at the step's start. `stance` is the stance leg's angle from the
    normal, positive while the hip is behind the foot (uphill). Over a step `gap` starts
    at 0 and turns negative, comes back through 0 rising (the swing leg overtakes the
    stance leg: `gap_rate > 0`) and falls through 0 at the heel strike, with `stance < 0`.
    The gap returned, `max(gap, stance, gap_rate)`, is positive from the start (`stance > 0`)
    through the scuffing (`gap_rate > 0` where the stance leg is already past the normal, as
    in the simplest walker's short-period gait) and equals `gap` near the heel strike,
    where `stance < 0` and `gap_rate < 0`.
    """
    return jnp.maximum(gap, jnp.maximum(stance, gap_rate))


@final
class HeelStrike(AbstractContact):
    """The swing foot of an `AbstractWalkerDynamics` landing on the slope.

    One surface, `front_gap`; its map is the walker's `heel_strike`. `max_events` bounds
    the heel strikes of one env step (a failed step beyond).
    """

    max_events: int = option(8, None)

    def gaps(self, dynamics: AbstractWalkerDynamics, y: State) -> Float[Array, " 1"]:
        return jnp.reshape(dynamics.front_gap(y), (1,))

    def impact(self, dynamics: AbstractWalkerDynamics, y: State, surface: int) -> State:
        del surface
        return dynamics.heel_strike(y)

    def check(self, dynamics) -> None:
        if not isinstance(dynamics, AbstractWalkerDynamics):
            raise ValueError(f"HeelStrike lands a walker's swing foot, and {type(dynamics).__name__} is no walker")


__all__ = ["AbstractWalkerDynamics", "HeelStrike", "swing_gap"]
