"""Generalised-force add-ons (temporary adapter onto CartPoleDynamics' own fields; replaced by
the add-on module of the `addons` branch)."""

import equinox as eqx

from .._fields import NONNEGATIVE, POSITIVE_OR_INF, AbstractParametrised, parameter
from .._types import Scalar
from ._base import AbstractDynamics


class JointDamping(AbstractParametrised):
    joint_damping: Scalar = parameter(0.0, NONNEGATIVE)


class EndStops(AbstractParametrised):
    end_stop_stiffness: Scalar = parameter(0.0, NONNEGATIVE)
    end_stop_damping: Scalar = parameter(0.0, NONNEGATIVE)
    track_limit: Scalar = parameter(2.4, POSITIVE_OR_INF)


class ForcedDynamics(AbstractDynamics):
    dynamics: AbstractDynamics
    forces: tuple

    def __init__(self, dynamics, forces):
        self.dynamics = dynamics
        self.forces = forces

    @property
    def velocity_indices(self):
        return self.dynamics.velocity_indices

    def _combined(self):
        d = self.dynamics
        for force in self.forces:
            for name in ("joint_damping", "end_stop_stiffness", "end_stop_damping", "track_limit"):
                if hasattr(force, name):
                    d = eqx.tree_at(lambda m: getattr(m, name), d, getattr(force, name))
        return d

    def vector_field(self, t, y, u):
        return self._combined().vector_field(t, y, u)

    def energy(self, y):
        return self._combined().energy(y)
