"""Integrating a vector field over one env step with any diffrax solver.

`Integrator` bundles a diffrax solver, a step-size controller, a step budget and an
adjoint. `make_integrator` turns a preset name (`"euler"`, `"rk4"`, `"tsit5"`, ...) or a
solver object into one, refusing pairings that would silently produce garbage.
"""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix
# diffrax's marker for "take this tolerance from the step-size controller" (not re-exported).
from diffrax._root_finder import use_stepsize_tol

from ._checks import check_count
from ._semi_implicit import ProjectedODETerm as ProjectedODETerm, SemiImplicitEuler as SemiImplicitEuler
from ._types import Array, BoolScalar, Input, IntScalar, ScalarLike, State
from .gradients import warn_if_silent


_rk4_tableau = diffrax.ButcherTableau(
    c=np.array([0.5, 0.5, 1.0]),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    # Classic RK4 has no embedded method; a zero error estimate marks that. It would make
    # an adaptive controller accept every step, so `make_integrator` refuses the pairing.
    b_error=np.zeros(4),
    a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
)


class RK4(diffrax.AbstractERK):
    """Classic fourth-order Runge--Kutta method (Kutta, 1901) as a diffrax solver.

    Four stages, no error estimate: use it with `diffrax.ConstantStepSize` (or
    `diffrax.StepTo`). Third-order Hermite interpolation for dense output.
    """

    tableau: ClassVar[diffrax.ButcherTableau] = _rk4_tableau
    interpolation_cls: ClassVar[Callable[..., diffrax.AbstractLocalInterpolation]] = (
        diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        return 4


def _implicit_root_finder():
    # With diffrax 0.7.2 and optimistix 0.1.0 the default VeryChord rejects about half
    # of Kvaerno5's steps on stiff problems; Chord with the controller's tolerances does not.
    return diffrax.with_stepsize_controller_tols(optimistix.Chord)()


def _fixed_step_root_finder():
    # A constant step size has no tolerances for the root finder to borrow, and diffrax
    # refuses to guess them; these are tight enough that the Newton error stays below the
    # truncation error of any fixed step worth taking, and loose enough for float32.
    return optimistix.Chord(rtol=1e-6, atol=1e-6, norm=optimistix.rms_norm)


def _uses_controller_tolerances(solver: diffrax.AbstractSolver) -> bool:
    root_finder = getattr(solver, "root_finder", None)
    return any(
        getattr(root_finder, name, None) is use_stepsize_tol for name in ("rtol", "atol", "norm")
    )


def _adaptive(rtol: float, atol: float) -> diffrax.PIDController:
    return diffrax.PIDController(rtol=rtol, atol=atol)


# name -> (solver factory, default controller factory, order of the method)
_PRESETS: dict[str, tuple[Callable[[], diffrax.AbstractSolver], Callable[[], diffrax.AbstractStepSizeController]]] = {
    "euler": (diffrax.Euler, diffrax.ConstantStepSize),
    "heun": (diffrax.Heun, diffrax.ConstantStepSize),
    "midpoint": (diffrax.Midpoint, diffrax.ConstantStepSize),
    "ralston": (diffrax.Ralston, diffrax.ConstantStepSize),
    "rk4": (RK4, diffrax.ConstantStepSize),
    "tsit5": (diffrax.Tsit5, lambda: _adaptive(1e-6, 1e-9)),
    "dopri5": (diffrax.Dopri5, lambda: _adaptive(1e-6, 1e-9)),
    "dopri8": (diffrax.Dopri8, lambda: _adaptive(1e-8, 1e-11)),
    "kvaerno5": (lambda: diffrax.Kvaerno5(root_finder=_implicit_root_finder()), lambda: _adaptive(1e-6, 1e-9)),
    "implicit_euler": (lambda: diffrax.ImplicitEuler(root_finder=_implicit_root_finder()), lambda: _adaptive(1e-3, 1e-6)),
    "kvaerno3": (lambda: diffrax.Kvaerno3(root_finder=_implicit_root_finder()), lambda: _adaptive(1e-6, 1e-9)),
    "kvaerno4": (lambda: diffrax.Kvaerno4(root_finder=_implicit_root_finder()), lambda: _adaptive(1e-6, 1e-9)),
    "semi_implicit_euler": (SemiImplicitEuler, diffrax.ConstantStepSize),
}

# Implicit presets: with a constant step size their root finder gets explicit tolerances.
_IMPLICIT_PRESETS = {
    "implicit_euler": diffrax.ImplicitEuler,
    "kvaerno3": diffrax.Kvaerno3,
    "kvaerno4": diffrax.Kvaerno4,
    "kvaerno5": diffrax.Kvaerno5,
}

SOLVER_PRESETS: tuple[str, ...] = tuple(_PRESETS)
"""Names accepted wherever a solver is: `make_integrator("rk4")`, `CartPole(solver="tsit5")`."""


def has_error_estimate(solver: diffrax.AbstractSolver) -> bool:
    """Whether `solver` provides the local error estimate an adaptive controller needs."""
    if isinstance(solver, SemiImplicitEuler):
        return False
    tableau = getattr(solver, "tableau", None)
    if isinstance(tableau, diffrax.ButcherTableau):
        return bool(np.any(np.asarray(tableau.b_error) != 0))
    # Any other solver: take one abstract step of a scalar ODE and look at its error output.
    term = diffrax.ODETerm(lambda t, y, args: -y)
    y0 = jnp.ones(())

    def probe():
        state = solver.init(term, 0.0, 0.1, y0, None)
        return solver.step(term, 0.0, 0.1, y0, None, state, made_jump=False)[1]

    try:
        return jax.eval_shape(probe) is not None
    except Exception:
        # Not an ODE solver of a single term (e.g. an IMEX `MultiTerm` solver): let
        # diffrax judge at solve time.
        return True


class Integrator(eqx.Module):
    """How one env step integrates the vector field over `[0, dt]`, the input held fixed.

    - `solver`: any diffrax solver.
    - `stepsize_controller`: `ConstantStepSize` (then `substeps` equal steps per env
      step) or an adaptive controller such as `PIDController`.
    - `max_steps`: the step budget of one env step; exhausting it is reported as
      `solver_ok=False`, never raised.
    - `adjoint`: how gradients pass through the solve.
    """

    solver: diffrax.AbstractSolver
    stepsize_controller: diffrax.AbstractStepSizeController
    adjoint: diffrax.AbstractAdjoint
    max_steps: int = eqx.field(static=True)
    substeps: int = eqx.field(static=True)

    def __init__(
        self,
        solver: diffrax.AbstractSolver,
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        *,
        max_steps: int | None = None,
        adjoint: diffrax.AbstractAdjoint | None = None,
        substeps: int = 1,
    ):
        if not isinstance(solver, diffrax.AbstractSolver):
            raise TypeError(
                f"solver must be a diffrax solver or one of {SOLVER_PRESETS}, got {solver!r}"
            )
        if stepsize_controller is None:
            stepsize_controller = diffrax.ConstantStepSize()
        if not isinstance(stepsize_controller, diffrax.AbstractStepSizeController):
            raise TypeError(
                f"stepsize_controller must be a diffrax step-size controller, got {stepsize_controller!r}"
            )
        check_count(substeps, "substeps")
        adaptive = isinstance(stepsize_controller, diffrax.AbstractAdaptiveStepSizeController)
        if adaptive and not has_error_estimate(solver):
            raise ValueError(
                f"solver {type(solver).__name__} has no error estimate, so it cannot be paired "
                f"with the adaptive stepsize_controller {type(stepsize_controller).__name__}: "
                "every step would be accepted and the result would be garbage. Use "
                "diffrax.ConstantStepSize() (with `substeps` for accuracy) or a solver with an "
                "embedded error estimate, such as 'tsit5'."
            )
        if not adaptive and _uses_controller_tolerances(solver):
            raise ValueError(
                f"the implicit solver {type(solver).__name__} takes its root finder's tolerances "
                f"from the step-size controller, but {type(stepsize_controller).__name__} has none. "
                "Use an adaptive controller such as diffrax.PIDController(rtol=1e-6, atol=1e-9) "
                "(recommended: a failed Newton solve then shrinks the step instead of failing "
                "the env step), or give the root finder explicit tolerances, e.g. "
                f"diffrax.{type(solver).__name__}(root_finder=optimistix.Chord(rtol=1e-6, "
                "atol=1e-6, norm=optimistix.rms_norm)), as the implicit presets do."
            )
        if max_steps is None:
            if isinstance(stepsize_controller, diffrax.StepTo):
                max_steps = len(stepsize_controller.ts) - 1
            else:
                max_steps = 4096 if adaptive else substeps
        check_count(max_steps, "max_steps")
        self.solver = solver
        self.stepsize_controller = stepsize_controller
        self.adjoint = diffrax.RecursiveCheckpointAdjoint() if adjoint is None else adjoint
        warn_if_silent(self.adjoint)
        self.max_steps = max_steps
        self.substeps = substeps

    @property
    def adaptive(self) -> bool:
        return isinstance(self.stepsize_controller, diffrax.AbstractAdaptiveStepSizeController)

    @property
    def _single_step(self) -> bool:
        # One constant step whose gradient is the plain derivative of the step: the
        # solver's own `step` is called directly. `diffeqsolve` would run it inside its
        # step loop, which XLA cannot fuse with the rest of an env step (about a tenth of
        # a vmapped CartPole step, see benchmarks/profile_step.py); the result is the same.
        return (
            type(self.stepsize_controller) is diffrax.ConstantStepSize
            and self.substeps == 1
            and isinstance(self.adjoint, (diffrax.RecursiveCheckpointAdjoint, diffrax.ForwardMode))
        )

    def integrate(
        self,
        vector_field: Callable[[ScalarLike, State, Input], State],
        y0: State,
        u: Input,
        dt: ScalarLike,
        *,
        projection: Callable[[State], State] | None = None,
        velocity_indices: tuple[int, ...] | None = None,
    ) -> tuple[State, dict[str, Array]]:
        """Solve `dy/dt = vector_field(t, y, u)` over `[0, dt]` from `y0`.

        `projection` (idempotent) maps states onto the admissible set (speed limits,
        walls, angle wrapping): it is applied to the end state whatever the solver, and
        inside the step by solvers that know of it (`SemiImplicitEuler`, between its
        velocity and position updates). `velocity_indices` names the velocity components
        of a second-order state, which `SemiImplicitEuler` needs.

        Returns the state at `dt` and `{"solver_ok", "solver_steps",
        "solver_rejected_steps"}` (accepted and rejected steps). `solver_ok` is
        False when the solver failed (step budget exhausted, step size collapsed, root
        finder diverged) or the state is not finite; the state is then not to be used.
        """
        dt = jnp.asarray(dt, dtype=y0.dtype)
        # An adaptive controller picks its own first step (Hairer's heuristic). A first
        # trial step of the whole `dt` can overflow on a stiff problem, and the
        # PIDController turns the resulting NaN error into a NaN step size that rejects
        # every later step (Van der Pol, mu=1e3, dt=10: 0 of 4096 steps accepted).
        dt0 = dt / self.substeps if isinstance(self.stepsize_controller, diffrax.ConstantStepSize) else None
        if projection is None and velocity_indices is None:
            term = diffrax.ODETerm(vector_field)
        else:
            optional = {} if projection is None else {"projection": projection}
            term = ProjectedODETerm(vector_field, velocity_indices=velocity_indices, **optional)
        if self._single_step:
            return self._step_once(term, y0, u, dt, projection)
        solution = diffrax.diffeqsolve(
            term,
            self.solver,
            t0=jnp.zeros((), dtype=y0.dtype),
            t1=dt,
            dt0=dt0,
            y0=y0,
            args=u,
            stepsize_controller=self.stepsize_controller,
            max_steps=self.max_steps,
            adjoint=self.adjoint,
            throw=False,
        )
        steps: IntScalar = solution.stats["num_accepted_steps"]
        rejected: IntScalar = solution.stats["num_steps"] - steps
        solved = solution.result == diffrax.RESULTS.successful
        return self._finish(solution.ys[-1], solved, steps, rejected, projection)

    def _step_once(self, term, y0, u, dt, projection):
        solver = self.solver
        if isinstance(solver, diffrax.AbstractERK) and isinstance(solver.tableau, diffrax.ButcherTableau):
            y1 = _explicit_runge_kutta_step(solver.tableau, term, y0, u, dt)
            return self._finish(y1, jnp.asarray(True), jnp.asarray(1), jnp.asarray(0), projection)
        if isinstance(solver, diffrax.AbstractRungeKutta) and solver.scan_kind is None:
            # As `diffeqsolve` sets it for the adjoint: a Runge-Kutta method's stage loop
            # is by default checkpointed, which forward-mode autodiff cannot pass through.
            kind = "lax" if isinstance(self.adjoint, diffrax.ForwardMode) else "bounded"
            solver = eqx.tree_at(lambda s: s.scan_kind, solver, kind, is_leaf=lambda x: x is None)
        t0 = jnp.zeros((), dtype=y0.dtype)
        solver_state = solver.init(term, t0, dt, y0, u)
        y1, _, _, _, result = solver.step(term, t0, dt, y0, u, solver_state, made_jump=False)
        # Counts as `diffeqsolve` reports them: one accepted step, none rejected.
        return self._finish(y1, result == diffrax.RESULTS.successful, jnp.asarray(1), jnp.asarray(0), projection)

    @staticmethod
    def _finish(y1, solved, steps, rejected, projection):
        # Checked before the projection too: clipping an infinite speed to its bound
        # would otherwise make a diverged solve look finite.
        finite = jnp.all(jnp.isfinite(y1))
        if projection is not None:
            y1 = projection(y1)
        ok: BoolScalar = solved & finite & jnp.all(jnp.isfinite(y1))
        info = {"solver_ok": ok, "solver_steps": steps, "solver_rejected_steps": rejected}
        return y1, info


def _explicit_runge_kutta_step(tableau: diffrax.ButcherTableau, term, y0: State, u: Input, dt) -> State:
    """One step of an explicit Runge-Kutta method from its Butcher tableau, stage by stage.

    What the solver's own `step` computes (up to rounding), written out: diffrax runs the
    stages in a loop (a `while` over a stage buffer, for its autodiff), which XLA cannot
    fuse; unrolled, a vmapped RK4 env step (Acrobot) is plain arithmetic, as a hand-written
    one is (`benchmarks/gym_vector.py`).
    """
    t0 = jnp.zeros((), dtype=y0.dtype)
    stages = [term.vf(t0, y0, u)]
    for c, a_row in zip(tableau.c, tableau.a_lower):
        increment = sum(float(a) * k for a, k in zip(a_row, stages) if a != 0)
        y = y0 if isinstance(increment, int) else y0 + dt * increment
        stages.append(term.vf(float(c) * dt, y, u))
    return y0 + dt * sum(float(b) * k for b, k in zip(tableau.b_sol, stages) if b != 0)


def make_integrator(
    solver: "str | diffrax.AbstractSolver | Integrator" = "euler",
    stepsize_controller: diffrax.AbstractStepSizeController | None = None,
    *,
    max_steps: int | None = None,
    adjoint: diffrax.AbstractAdjoint | None = None,
    substeps: int = 1,
) -> Integrator:
    """An `Integrator` from a preset name (see `SOLVER_PRESETS`) or a diffrax solver.

    A preset brings its default controller (`PIDController` for the embedded methods,
    `ConstantStepSize` for the others) unless `stepsize_controller` is given. A solver
    object defaults to `ConstantStepSize`.

    The implicit presets (`"implicit_euler"`, `"kvaerno3"`, `"kvaerno4"`, `"kvaerno5"`)
    solve their stages with `optimistix.Chord` at the controller's tolerances (diffrax's
    default `VeryChord` rejects about half of Kvaerno5's steps: Van der Pol at mu = 1e3
    takes 7496 steps instead of 775, see `benchmarks/results/root_finders.md`). Under a
    constant step size they get explicit tolerances (1e-6) instead; an implicit solver
    object without them is refused there.
    """
    if isinstance(solver, Integrator):
        if stepsize_controller is not None or max_steps is not None or adjoint is not None or substeps != 1:
            raise ValueError("pass either an Integrator or solver settings, not both")
        return solver
    if isinstance(solver, str):
        key = solver.lower()
        if key not in _PRESETS:
            raise ValueError(f"solver must be one of {SOLVER_PRESETS} or a diffrax solver, got {solver!r}")
        make_solver, make_controller = _PRESETS[key]
        if stepsize_controller is None:
            stepsize_controller = make_controller()
        if key in _IMPLICIT_PRESETS and not isinstance(
            stepsize_controller, diffrax.AbstractAdaptiveStepSizeController
        ):
            solver = _IMPLICIT_PRESETS[key](root_finder=_fixed_step_root_finder())
        else:
            solver = make_solver()
    return Integrator(
        solver, stepsize_controller, max_steps=max_steps, adjoint=adjoint, substeps=substeps
    )
