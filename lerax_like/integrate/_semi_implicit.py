"""Semi-implicit Euler with a projection: the step of Gymnasium's Pendulum and MountainCars.

Those envs are not a pure ODE step. They update the velocity, clip it, update the
position with the new velocity, then clip the position (and, for MountainCar, stop the
car at the left wall): `SemiImplicitEuler` on a `ProjectedODETerm`, which every other
diffrax solver reads as the plain `ODETerm` it is (the `Integrator` applies the projection
after their step). With each scene's projection this reproduces Gymnasium's update to the
last few ulps.
"""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import equinox as eqx
import numpy as np

from .._types import State


def _identity(y: State) -> State:
    return y


class ProjectedODETerm(diffrax.ODETerm):
    """`dy/dt = vector_field(t, y, args)`, with the structure a partitioned solver needs.

    - `projection`: maps a state onto the admissible set (identity if unconstrained).
      It must be idempotent: a solver may apply it more than once per step.
    - `velocity_indices`: the components of `y` that are velocities, in a second-order
      system `y = (q, v)`; `None` if the system is not declared second order.
    """

    projection: Callable[[State], State] = _identity
    velocity_indices: tuple[int, ...] | None = eqx.field(static=True, default=None)


class SemiImplicitEuler(diffrax.AbstractSolver):
    """Semi-implicit (symplectic) Euler for a flat state `y = (q, v)` with a projection.

    One step of size `h` from `(q0, v0)`:

        v1 = v0 + h * f_v(t0, q0, v0);          (q0, v1) <- projection(q0, v1)
        q1 = q0 + h * f_q(t0, q0, v1);          (q1, v1) <- projection(q1, v1)

    For a separable mechanical system (`f_q = v`, `f_v` independent of `v`) this is the
    symplectic Euler method; otherwise it is a first-order partitioned Euler method.
    Gymnasium's Pendulum-v1 and both MountainCars are exactly this step (with `h = dt`),
    their speed clip being the first projection and their position clip and left wall
    the second.

    Unlike `diffrax.SemiImplicitEuler`, which takes a pair of terms and a pair of
    states, this solver takes one `ProjectedODETerm` on a flat state and lets the
    velocity update depend on the velocity (friction, Coriolis terms). First order, no
    error estimate: use it with `diffrax.ConstantStepSize`.
    """

    term_structure: ClassVar = diffrax.AbstractTerm
    interpolation_cls: ClassVar[Callable[..., diffrax.LocalLinearInterpolation]] = (
        diffrax.LocalLinearInterpolation
    )

    def order(self, terms):
        return 1

    def init(self, terms, t0, t1, y0, args):
        return None

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del solver_state, made_jump
        # diffeqsolve hands solvers its terms wrapped (in diffrax's private `WrapTerm`,
        # for the time direction): the structure is read from the wrapped term.
        inner = terms
        while not isinstance(inner, ProjectedODETerm) and isinstance(getattr(inner, "term", None), diffrax.AbstractTerm):
            inner = inner.term
        velocity_indices = getattr(inner, "velocity_indices", None)
        if velocity_indices is None:
            raise ValueError(
                "SemiImplicitEuler needs to know which state components are velocities: "
                "the dynamics must declare `velocity_indices` (a ProjectedODETerm built by "
                "`Integrator.integrate(..., velocity_indices=...)`)."
            )
        velocities = np.asarray(velocity_indices)
        positions = np.setdiff1d(np.arange(y0.shape[-1]), velocities)
        project = inner.projection
        control = terms.contr(t0, t1)
        rate = terms.vf(t0, y0, args)
        y_half = project(y0.at[velocities].set(y0[velocities] + rate[velocities] * control))
        rate = terms.vf(t0, y_half, args)
        y1 = project(y_half.at[positions].set(y_half[positions] + rate[positions] * control))
        dense_info = dict(y0=y0, y1=y1)
        return y1, None, dense_info, None, diffrax.RESULTS.successful

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)
