"""The `Integrator`: how one env step integrates the vector field, and `make_integrator`."""

import dataclasses
import warnings
from collections.abc import Callable
from typing import Any

import diffrax
import equinox as eqx
import jax.core  # `jax.core.Tracer`: imported by name, so that a type checker sees the module
import jax.numpy as jnp

from .._fields import check_count
from .._types import Array, BoolScalar, Input, IntScalar, ScalarLike, State
from ._adjoint import sized_to_the_work, warn_if_silent
from ._controller import GuardedPIDController
from ._dense import HermiteDenseOutput, needs_hermite_dense_output
from ._facts import has_error_estimate
from ._presets import SOLVERS
from ._root_finder import uses_controller_tolerances
from ._semi_implicit import ProjectedODETerm


class EpisodeTime(eqx.Module):
    """`vector_field` read at the episode's time: `t0 + s` at the solve's time `s`.

    A step's solve runs over `[0, dt]`, whatever the episode's time `t0` at its start:
    shifting the time inside the term rather than solving over `[t0, t0 + dt]` keeps the
    solver's step sizes (which `t1 - t0` would round differently at every `t0`), so an
    autonomous field's results do not depend on `t0`, bit for bit.
    """

    vector_field: Callable[[ScalarLike, State, Input], State]
    t0: ScalarLike

    def __call__(self, s: ScalarLike, y: State, u: Input) -> State:
        return self.vector_field(self.t0 + s, y, u)


class Integrator(eqx.Module):
    """How one env step integrates the vector field over `[0, dt]`, the input held fixed.

    The field gets the episode's time (`t0 + s`, `EpisodeTime`) when the caller gives `t0`.

    - `solver`: any diffrax solver.
    - `stepsize_controller`: `ConstantStepSize` (then `substeps` equal steps per env
      step) or an adaptive controller such as `PIDController`.
    - `max_steps`: the step budget of one env step; exhausting it is reported as
      `solver_ok=False`, never raised.
    - `adjoint`: how gradients pass through the solve (`with_adjoint` replaces it).
    - `preset_tolerances`: whether the controller's tolerances are a preset's default
      (`make_integrator("tsit5")`): those follow the dtype the solve runs in, raised
      silently to what it can meet (`tolerance_floors`); a user's tolerance below the floor
      is raised too, with a warning that names it, the floor and the dtype.

    The three are held split (`*_arrays`, `*_static`): their arrays are leaves (a
    tolerance given as an array is traced, so one compilation serves a sweep of them),
    everything else (a controller's `norm` function, diffrax's marker for tolerances taken
    from the controller, Python numbers and flags) is static. Every leaf of an env is then
    an array, so an env is a valid argument of plain `jax.jit` and `jax.grad`, not only of
    `eqx.filter_jit`, whatever the solver, controller and adjoint; under `eqx.filter_jit`
    nothing changes (it holds non-arrays static too).
    """

    solver_arrays: Any
    solver_static: Any = eqx.field(static=True)
    controller_arrays: Any
    controller_static: Any = eqx.field(static=True)
    adjoint_arrays: Any
    adjoint_static: Any = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    substeps: int = eqx.field(static=True)
    preset_tolerances: bool = eqx.field(static=True)

    def __init__(
        self,
        solver: diffrax.AbstractSolver,
        stepsize_controller: diffrax.AbstractStepSizeController | None = None,
        *,
        max_steps: int | None = None,
        adjoint: diffrax.AbstractAdjoint | None = None,
        substeps: int = 1,
        preset_tolerances: bool = False,
    ):
        if not isinstance(solver, diffrax.AbstractSolver):
            raise TypeError(f"solver must be a diffrax solver or one of {SOLVERS.names}, got {solver!r}")
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
        if not adaptive and uses_controller_tolerances(solver):
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
        self.solver_arrays, self.solver_static = eqx.partition(solver, eqx.is_array)
        self.controller_arrays, self.controller_static = eqx.partition(stepsize_controller, eqx.is_array)
        adjoint = diffrax.RecursiveCheckpointAdjoint() if adjoint is None else adjoint
        if not isinstance(adjoint, diffrax.AbstractAdjoint):
            raise TypeError(f"adjoint must be a diffrax adjoint, got {adjoint!r}")
        warn_if_silent(adjoint)
        adjoint = sized_to_the_work(adjoint, max_steps)
        self.adjoint_arrays, self.adjoint_static = eqx.partition(adjoint, eqx.is_array)
        self.max_steps = max_steps
        self.substeps = substeps
        self.preset_tolerances = bool(preset_tolerances)

    @property
    def solver(self) -> diffrax.AbstractSolver:
        """The diffrax solver."""
        return eqx.combine(self.solver_arrays, self.solver_static)

    @property
    def stepsize_controller(self) -> diffrax.AbstractStepSizeController:
        """The step-size controller."""
        return eqx.combine(self.controller_arrays, self.controller_static)

    @property
    def adjoint(self) -> diffrax.AbstractAdjoint:
        """How gradients pass through the solve."""
        return eqx.combine(self.adjoint_arrays, self.adjoint_static)

    def with_adjoint(self, adjoint: diffrax.AbstractAdjoint) -> "Integrator":
        """This integrator with `adjoint` in place of its own."""
        return Integrator(
            self.solver, self.stepsize_controller, max_steps=self.max_steps, adjoint=adjoint, substeps=self.substeps,
            preset_tolerances=self.preset_tolerances,
        )

    def stepsize_controller_for(self, dtype) -> diffrax.AbstractStepSizeController:
        """The step-size controller as a solve in `dtype` runs it: a `PIDController`'s tolerances
        raised to `tolerance_floors(dtype)` (a preset's silently, a user's with a warning)."""
        controller = self.stepsize_controller
        if isinstance(controller, diffrax.PIDController):
            controller = _within_floors(controller, dtype, quiet=self.preset_tolerances)
        return controller

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

    def _term_and_first_step(self, vector_field, y0, dt, t0, projection, velocity_indices):
        """`dt` in `y0`'s dtype, the term to solve and the first step, as every solve here takes them."""
        dt = jnp.asarray(dt, dtype=y0.dtype)
        vector_field = EpisodeTime(vector_field, jnp.asarray(t0, dtype=dt.dtype))
        # An adaptive controller picks its own first step (Hairer's heuristic). A first
        # trial step of the whole `dt` can overflow on a stiff problem, and the
        # PIDController turns the resulting NaN error into a NaN step size that rejects
        # every later step (Van der Pol, mu=1e3, dt=10: 0 of 4096 steps accepted).
        dt0 = dt / self.substeps if isinstance(self.stepsize_controller, diffrax.ConstantStepSize) else None
        if projection is None and velocity_indices is None:
            return dt, diffrax.ODETerm(vector_field), dt0
        optional = {} if projection is None else {"projection": projection}
        return dt, ProjectedODETerm(vector_field, velocity_indices=velocity_indices, **optional), dt0

    def integrate(
        self,
        vector_field: Callable[[ScalarLike, State, Input], State],
        y0: State,
        u: Input,
        dt: ScalarLike,
        *,
        projection: Callable[[State], State] | None = None,
        velocity_indices: tuple[int, ...] | None = None,
        t0: ScalarLike = 0.0,
    ) -> tuple[State, dict[str, Array]]:
        """Solve `dy/dt = vector_field(t, y, u)` over `[t0, t0 + dt]` from `y0`.

        The solve runs over `[0, dt]` with the field read at `t0 + s` (`EpisodeTime`): `t0`
        is the episode's time at the step's start (`lerax_like.env.episode_time`).

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
        dt, term, dt0 = self._term_and_first_step(vector_field, y0, dt, t0, projection, velocity_indices)
        if self._single_step:
            return self._step_once(term, y0, u, dt, projection)
        solution = self._solve(term, y0, u, dt, dt0, adjoint=self.adjoint)
        steps: IntScalar = solution.stats["num_accepted_steps"]
        rejected: IntScalar = solution.stats["num_steps"] - steps
        solved = solution.result == diffrax.RESULTS.successful
        return self._finish(_saved_states(solution)[-1], solved, steps, rejected, projection)

    def dense_states(
        self,
        vector_field: Callable[[ScalarLike, State, Input], State],
        y0: State,
        u: Input,
        dt: ScalarLike,
        ts: Array,
        *,
        projection: Callable[[State], State] | None = None,
        velocity_indices: tuple[int, ...] | None = None,
        t0: ScalarLike = 0.0,
    ) -> tuple[Array, BoolScalar]:
        """The solver's own dense output of the solve `integrate` makes, at times `ts` in `[0, dt]`
        from the step's start (the field read at `t0 + s`, as in `integrate`).

        Same solver, controller, first step and budget as `integrate`, so the same steps;
        between them the solver's interpolation: the methods' own for Tsit5, Dopri5 and
        Dopri8, linear for the Euler methods, and `HermiteDenseOutput`'s for the other
        explicit Runge--Kutta methods, a user's tableau included. No projection is applied to the interpolated states. Returns the states, shape
        `(len(ts), n)`, and whether the solve succeeded.
        """
        dt, term, dt0 = self._term_and_first_step(vector_field, y0, dt, t0, projection, velocity_indices)
        solver = self.solver
        if needs_hermite_dense_output(solver):
            solver = HermiteDenseOutput(solver)
        saveat = diffrax.SaveAt(ts=jnp.asarray(ts, dtype=y0.dtype))
        solution = self._solve(term, y0, u, dt, dt0, saveat=saveat, solver=solver)
        return _saved_states(solution), solution.result == diffrax.RESULTS.successful

    def failure(self, vector_field, y0: State, u: Input, dt: ScalarLike, **options) -> str:
        """Why `integrate` with the same arguments (`options`: its keywords) fails, in words;
        `""` if it does not.

        The solve again, with diffrax's result kept: `"step budget exhausted"` (`max_steps`
        solver steps within one env step), `"step size collapsed"`, `"root finder failed"`
        (an implicit solver's Newton iteration), or `"non-finite state"` when the solve
        ended but its state is not finite (a solver without an error estimate, or a
        projection of one). For a study's failed row (`lerax_like.analysis`), not for a
        hot loop: it runs eagerly, once.
        """
        projection = options.get("projection")
        dt, term, dt0 = self._term_and_first_step(
            vector_field, y0, dt, options.get("t0", 0.0), projection, options.get("velocity_indices")
        )
        solution = self._solve(term, y0, u, dt, dt0, adjoint=self.adjoint)
        assert solution.ys is not None  # saved at t1
        y1 = solution.ys[-1]
        finite = bool(jnp.all(jnp.isfinite(y1))) and (projection is None or bool(jnp.all(jnp.isfinite(projection(y1)))))
        words = (  # diffrax's results are not hashable: pairs, not a dict
            (diffrax.RESULTS.successful, "" if finite else "non-finite state"),
            (diffrax.RESULTS.max_steps_reached, f"step budget exhausted ({self.max_steps} solver steps per env step)"),
            (diffrax.RESULTS.dt_min_reached, "step size collapsed (the controller's dtmin)"),
        )
        for result, text in words:
            if bool(solution.result == result):
                return text
        return f"root finder failed or solver error: {diffrax.RESULTS[solution.result]}"

    def _solve(self, term, y0, u, dt, dt0, *, solver=None, **options) -> diffrax.Solution:
        """`diffeqsolve` over `[0, dt]` with this integrator's solver, controller and budget."""
        solver = self.solver if solver is None else solver
        controller = self.stepsize_controller_for(y0.dtype)
        if type(controller) is diffrax.PIDController:
            controller = GuardedPIDController(**{f.name: getattr(controller, f.name) for f in dataclasses.fields(controller)})
        return diffrax.diffeqsolve(
            term, solver, t0=jnp.zeros((), dtype=y0.dtype), t1=dt, dt0=dt0, y0=y0, args=u,
            stepsize_controller=controller, max_steps=self.max_steps, throw=False, **options,
        )

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


def tolerance_floors(dtype, *, preset: bool = False) -> tuple[float, float]:
    """The smallest `(rtol, atol)` that a solve in `dtype` runs at, from the dtype's `eps`.

    `rtol`: `100 eps`, SciPy's `solve_ivp` floor: below it the error estimate, the difference
    of two solutions that agree to a few units in the last place, is rounding, and the
    controller shrinks the step chasing it. `atol`: `eps`, the spacing of floating-point
    numbers at a state of unit scale (an absolute tolerance has the state's units, so no
    finer floor holds for every scene). A preset's tolerances (`preset=True`) keep the
    margin on both: `100 eps`. In float64 (eps 2.2e-16) every preset's tolerances are above
    these; in float32 (eps 1.2e-7) Tsit5's `1e-6, 1e-9` become `1.2e-5, 1.2e-5`. Measured
    (CartPole, pole_mass=0.2, joint_damping=300, kvaerno5): at float32 with `1e-6, 1e-9`,
    207 solver steps per env step against 21 in float64; at `1.2e-5, 1.2e-5`, 7.
    """
    eps = float(jnp.finfo(dtype).eps)
    return 100 * eps, (100 * eps if preset else eps)


def _within_floors(controller: diffrax.PIDController, dtype, *, quiet: bool) -> diffrax.PIDController:
    """`controller` with `rtol` and `atol` raised to `tolerance_floors(dtype)`, with one warning
    naming those raised unless they are a preset's (`quiet`). A Python number stays one (the
    solve then compiles as before); a traced tolerance is raised with `jnp.maximum`, unwarned."""
    raised = []
    for name, floor in zip(("rtol", "atol"), tolerance_floors(dtype, preset=quiet)):
        value = getattr(controller, name)
        if isinstance(value, jax.core.Tracer):
            new = jnp.maximum(value, floor)
        elif float(value) < floor:
            raised.append(f"{name}={float(value):.3g} to {floor:.3g}")
            new = floor if isinstance(value, (int, float)) else jnp.asarray(floor, dtype=jnp.result_type(value))
        else:
            continue
        controller = eqx.tree_at(lambda c: getattr(c, name), controller, new)
    if raised and not quiet:
        warnings.warn(
            f"{jnp.dtype(dtype).name} (eps {float(jnp.finfo(dtype).eps):.3g}) cannot meet the step-size controller's "
            f"tolerances; raised {' and '.join(raised)} (lerax_like.integrate.tolerance_floors). For tighter "
            "tolerances run in float64: jax.config.update('jax_enable_x64', True) at the start of the script.",
            stacklevel=2,
        )
    return controller


def _saved_states(solution: diffrax.Solution) -> Array:
    """The states a solve saved: `SaveAt(t1=True)` (diffeqsolve's default) or `SaveAt(ts=...)`
    here, never nothing, where diffrax types `ys` as possibly None."""
    if solution.ys is None:
        raise ValueError("the solve saved no states")
    return solution.ys


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
    """An `Integrator` from a preset name (see `SOLVERS.names`) or a diffrax solver.

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
    preset_tolerances = False
    if isinstance(solver, str):
        preset = SOLVERS.find(solver)
        if stepsize_controller is None:
            stepsize_controller = preset.make_controller()
            preset_tolerances = True
        adaptive = isinstance(stepsize_controller, diffrax.AbstractAdaptiveStepSizeController)
        if preset.make_fixed_step_solver is not None and not adaptive:
            solver = preset.make_fixed_step_solver()
        else:
            solver = preset.make_solver()
    return Integrator(
        solver, stepsize_controller, max_steps=max_steps, adjoint=adjoint, substeps=substeps,
        preset_tolerances=preset_tolerances,
    )
