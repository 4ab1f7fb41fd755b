"""What a numerical analyst asks of a solver first, read from the solver itself, in one place."""

import dataclasses

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._root_finder import fixed_step_root_finder, uses_controller_tolerances
from ._semi_implicit import ProjectedODETerm, SemiImplicitEuler


# The one-stage methods diffrax writes without a Butcher tableau, and ours; every other
# Runge--Kutta method's stages are read from its tableau.
_STAGES_WITHOUT_TABLEAU: dict[type, int] = {diffrax.Euler: 1, diffrax.ImplicitEuler: 1, SemiImplicitEuler: 2}


@dataclasses.dataclass(frozen=True)
class SolverFacts:
    """A solver's order, stages, cost in vector-field evaluations and error estimate.

    - `order`: what the solver declares (`solver.order(terms)` for an ODE term), `None`
      where it declares nothing.
    - `stages`: stages of one step (`None` if not a Runge--Kutta method, or unknown).
    - `evaluations_per_step`, `evaluations_per_rejected_step`, `evaluations_per_solve`:
      vector-field evaluations of an accepted step, of a rejected step, and once at the
      start of each solve. An explicit method of `s` stages costs `s` per step; a
      first-same-as-last one (Tsit5, Dopri5) `s - 1` per accepted step (its first stage is
      the last of the step before) plus one per solve, and all `s` for a rejected step
      (diffrax 0.7 does not reuse the first stage after a rejection: counted in
      tests/test_study.py). `None` for implicit methods, whose count depends on the root
      finder, and for solvers with no tableau to read.
    - `implicit`: whether a step solves a nonlinear system (`AbstractImplicitSolver`).
    - `error_estimate`: whether a step gives the local error estimate an adaptive
      controller needs.
    """

    order: int | None
    stages: int | None
    evaluations_per_step: int | None
    evaluations_per_rejected_step: int | None
    evaluations_per_solve: int | None
    implicit: bool
    error_estimate: bool


def solver_facts(solver: diffrax.AbstractSolver) -> SolverFacts:
    """The `SolverFacts` of a diffrax solver, read from its tableau and its own declarations.

    Raises `ValueError` for a solver that cannot step the single ODE term of an env step
    (an IMEX solver of a `MultiTerm`, an SDE solver of a pair of terms).
    """
    if not isinstance(solver, diffrax.AbstractSolver):
        raise TypeError(f"solver must be a diffrax solver, got {solver!r}")
    structure = solver.term_structure
    if not (isinstance(structure, type) and issubclass(diffrax.ODETerm, structure)):
        raise ValueError(
            f"solver {type(solver).__name__} steps terms of structure {structure}, but an env step "
            "integrates one ODE term dy/dt = f(t, y, u)"
        )
    implicit = isinstance(solver, diffrax.AbstractImplicitSolver)
    order = solver.order(diffrax.ODETerm(lambda t, y, args: -y))
    tableau = getattr(solver, "tableau", None)
    if isinstance(tableau, diffrax.ButcherTableau):
        stages = len(tableau.c) + 1
        error_estimate = bool(np.any(np.asarray(tableau.b_error) != 0))
        fsal = bool(tableau.fsal)
    else:
        stages = next((n for cls, n in _STAGES_WITHOUT_TABLEAU.items() if isinstance(solver, cls)), None)
        # diffrax declares a solver that returns error estimates an `AbstractAdaptiveSolver`;
        # an undeclared one is asked by a step.
        error_estimate = isinstance(solver, diffrax.AbstractAdaptiveSolver) or _steps_give_an_error_estimate(solver)
        fsal = False
    per_step = None if stages is None or implicit else stages - int(fsal)
    counted = per_step is not None
    return SolverFacts(
        order=None if order is None else int(order),
        stages=stages,
        evaluations_per_step=per_step,
        evaluations_per_rejected_step=stages if counted else None,
        evaluations_per_solve=int(fsal) if counted else None,
        implicit=implicit,
        error_estimate=error_estimate,
    )


def _steps_give_an_error_estimate(solver: diffrax.AbstractSolver) -> bool:
    # A solver with no tableau to read: take one abstract step (nothing is computed) of an
    # oscillator, declared second order for the partitioned solvers that need to know, and
    # see whether it returns an error estimate.
    if uses_controller_tolerances(solver):
        # Outside a solve there is no controller to lend its tolerances.
        solver = eqx.tree_at(lambda s: s.root_finder, solver, fixed_step_root_finder())
    term = ProjectedODETerm(lambda t, y, args: jnp.stack([y[1], -y[0]]), velocity_indices=(1,))

    def probe():
        # Made inside the abstract trace, so that nothing is computed and JAX's backend is
        # not started: `import lerax_like` builds the presets, and JAX options that are
        # read when the backend starts (its CPU dispatch) must still be settable after it.
        y0 = jnp.ones(2)
        t0, t1 = jnp.asarray(0.0), jnp.asarray(0.1)
        state = solver.init(term, t0, t1, y0, None)
        return solver.step(term, t0, t1, y0, None, state, made_jump=False)[1]

    return jax.eval_shape(probe) is not None


def has_error_estimate(solver: diffrax.AbstractSolver) -> bool:
    """Whether `solver` provides the local error estimate an adaptive controller needs."""
    return solver_facts(solver).error_estimate
