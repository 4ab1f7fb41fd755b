"""Integrating a vector field over one env step with any diffrax solver.

`Integrator` bundles a diffrax solver, a step-size controller, a step budget and an
adjoint. `make_integrator` turns a preset name (`"euler"`, `"rk4"`, `"tsit5"`, ...) or a
solver object into one, refusing pairings that would silently produce garbage.
"""

import dataclasses
import importlib
import types
from collections.abc import Callable, Mapping, Sequence
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix
# diffrax's marker for "take this tolerance from the step-size controller": diffrax (0.7)
# exports no public name for it, so this one private import stays.
from diffrax._root_finder import use_stepsize_tol

from ._fields import check_count
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


class GuardedPIDController(diffrax.PIDController):
    """`diffrax.PIDController`, which also shrinks the step after a trial step that diverged to infinity.

    diffrax 0.7.2 scales a step's error by `atol + rtol max(|y0|, |y1|)`, with `y0` alone
    when the candidate `y1` is NaN. A root finder that diverges to infinity (Kvaerno4 on
    Van der Pol at `mu = 1e3`) gives an infinite `y1` and error: `inf / inf` is NaN, so is
    the next step size, and every later step is rejected until `max_steps` (0 of 100000
    accepted). Here a non-finite candidate counts as NaN with an infinite error, which the
    controller rejects and answers with a step `factormin` times smaller. `Integrator`
    solves with this in place of a plain `PIDController` of the same settings.
    """

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        diverged = jnp.any(jnp.stack([jnp.any(~jnp.isfinite(y)) for y in jax.tree.leaves(y1_candidate)]))
        y1_candidate = jax.tree.map(lambda y: jnp.where(diverged, jnp.nan, y), y1_candidate)
        y_error = jax.tree.map(lambda e: jnp.where(diverged, jnp.inf, e), y_error)
        return super().adapt_step_size(t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state)


def _adaptive(rtol: float, atol: float) -> Callable[[], diffrax.PIDController]:
    return lambda: diffrax.PIDController(rtol=rtol, atol=atol)


@dataclasses.dataclass(frozen=True)
class SolverPreset:
    """A solver by name: how to build it, and what a numerical analyst asks of it first.

    - `name`: the name accepted wherever a solver is (`make_integrator(name)`,
      `CartPole(solver=name)`, `lerax-like study --solver name`).
    - `make_solver`: builds the solver (no arguments).
    - `order`: order of convergence of the method (global error `O(h^order)`).
    - `stages`: stages of one step (`None` if not a Runge--Kutta method);
      `evaluations_per_step`: vector-field evaluations of one accepted step, which is
      `stages - 1` for a first-same-as-last method.
    - `implicit`: whether a step solves a nonlinear system (diffrax's
      `AbstractImplicitSolver`).
    - `error_estimate`: whether the method has an embedded error estimate, which an
      adaptive controller needs.
    - `make_controller`: the default step-size controller (no arguments).
    - `make_fixed_step_solver`: for implicit methods, the solver to use under a constant
      step size, whose root finder has tolerances of its own (`None`: `make_solver`).
    - `description`: one line, for the listing of `lerax-like solvers`.
    """

    name: str
    make_solver: Callable[[], diffrax.AbstractSolver]
    order: int
    stages: int | None
    evaluations_per_step: int | None
    implicit: bool
    error_estimate: bool
    make_controller: Callable[[], diffrax.AbstractStepSizeController]
    make_fixed_step_solver: Callable[[], diffrax.AbstractSolver] | None = None
    description: str = ""

    @property
    def controller(self) -> str:
        """The default controller, in words (`"ConstantStepSize"`, `"PID rtol=1e-06 atol=1e-09"`)."""
        controller = self.make_controller()
        if isinstance(controller, diffrax.PIDController):
            return f"PID rtol={float(controller.rtol):.0e} atol={float(controller.atol):.0e}"
        return type(controller).__name__


def _implicit(cls: type[diffrax.AbstractImplicitSolver], root_finder) -> Callable[[], diffrax.AbstractSolver]:
    return lambda: cls(root_finder=root_finder())


def _builtin_presets() -> list[SolverPreset]:
    constant = diffrax.ConstantStepSize

    def explicit(name, make, order, stages, evaluations, estimate, controller, description):
        return SolverPreset(name, make, order, stages, evaluations, False, estimate, controller, None, description)

    def implicit(name, cls, order, stages, evaluations, controller, description):
        return SolverPreset(
            name, _implicit(cls, _implicit_root_finder), order, stages, evaluations, True, True, controller,
            _implicit(cls, _fixed_step_root_finder), description,
        )

    return [
        explicit("euler", diffrax.Euler, 1, 1, 1, False, constant, "forward Euler; Gymnasium's CartPole step"),
        explicit("heun", diffrax.Heun, 2, 2, 2, True, constant, "Heun's method (explicit trapezoidal), Euler embedded"),
        explicit("midpoint", diffrax.Midpoint, 2, 2, 2, True, constant, "explicit midpoint, Euler embedded"),
        explicit("ralston", diffrax.Ralston, 2, 2, 2, True, constant, "Ralston's second-order method, Euler embedded"),
        explicit("rk4", RK4, 4, 4, 4, False, constant, "classic Runge-Kutta (Kutta 1901)"),
        explicit("tsit5", diffrax.Tsit5, 5, 7, 6, True, _adaptive(1e-6, 1e-9), "Tsitouras 5(4), first same as last"),
        explicit("dopri5", diffrax.Dopri5, 5, 7, 6, True, _adaptive(1e-6, 1e-9), "Dormand-Prince 5(4), first same as last"),
        explicit("dopri8", diffrax.Dopri8, 8, 14, 13, True, _adaptive(1e-8, 1e-11), "Dormand-Prince 8(7), first same as last"),
        implicit("implicit_euler", diffrax.ImplicitEuler, 1, 1, None, _adaptive(1e-3, 1e-6), "backward Euler, L-stable"),
        implicit("kvaerno3", diffrax.Kvaerno3, 3, 4, None, _adaptive(1e-6, 1e-9), "Kvaerno 3(2) ESDIRK, L-stable"),
        implicit("kvaerno4", diffrax.Kvaerno4, 4, 5, None, _adaptive(1e-6, 1e-9), "Kvaerno 4(3) ESDIRK, L-stable"),
        implicit("kvaerno5", diffrax.Kvaerno5, 5, 7, None, _adaptive(1e-6, 1e-9), "Kvaerno 5(4) ESDIRK, L-stable"),
        explicit(
            "semi_implicit_euler", SemiImplicitEuler, 1, None, 2, False, constant,
            "symplectic Euler; Gymnasium's Pendulum and MountainCar step",
        ),
    ]


_REGISTRY: dict[str, SolverPreset] = {preset.name: preset for preset in _builtin_presets()}

SOLVERS: Mapping[str, SolverPreset] = types.MappingProxyType(_REGISTRY)
"""Every solver preset by name, the built-in ones and those added by `register_solver`."""


class _PresetNames(Sequence[str]):
    """The names in `SOLVERS`, in registration order; follows `register_solver`."""

    def __getitem__(self, index):
        return tuple(_REGISTRY)[index]

    def __len__(self) -> int:
        return len(_REGISTRY)

    def __repr__(self) -> str:
        return repr(tuple(_REGISTRY))


SOLVER_PRESETS: Sequence[str] = _PresetNames()
"""Names accepted wherever a solver is: `make_integrator("rk4")`, `CartPole(solver="tsit5")`."""


def register_solver(
    name: str,
    solver: "Callable[[], diffrax.AbstractSolver] | diffrax.AbstractSolver",
    *,
    order: int,
    stages: int | None = None,
    implicit: bool | None = None,
    error_estimate: bool | None = None,
    stepsize_controller: "Callable[[], diffrax.AbstractStepSizeController] | None" = None,
    description: str = "",
    replace: bool = False,
) -> SolverPreset:
    """Register a solver under `name`, usable wherever a preset name is.

    - `solver`: a diffrax solver, or a function (a solver class) that builds one with no
      arguments.
    - `order`: the method's order of convergence (a positive integer).
    - `stages`: stages per step (default: read from a Butcher tableau, if it has one).
    - `implicit`, `error_estimate`: default: read from the solver.
    - `stepsize_controller`: function returning the default controller (default:
      `PIDController(rtol=1e-6, atol=1e-9)` with an error estimate, else
      `ConstantStepSize`).
    - `replace`: allow replacing an existing preset of that name.

    Returns the `SolverPreset` added to `SOLVERS`.
    """
    if not isinstance(name, str) or not name or ":" in name or name != name.strip():
        raise ValueError(f"name must be a non-empty string without ':' or surrounding spaces, got {name!r}")
    key = name.lower()
    if key in _REGISTRY and not replace:
        raise ValueError(f"a solver preset {key!r} exists already; pass replace=True to replace it")
    if isinstance(solver, diffrax.AbstractSolver):
        instance = solver
        make_solver: Callable[[], diffrax.AbstractSolver] = lambda: instance
    elif callable(solver):
        make_solver = solver
        instance = solver()
        if not isinstance(instance, diffrax.AbstractSolver):
            raise TypeError(f"solver must build a diffrax solver with no arguments; it built {instance!r}")
    else:
        raise TypeError(f"solver must be a diffrax solver or a function building one, got {solver!r}")
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise ValueError(f"order must be a positive integer, got {order!r}")
    tableau = getattr(instance, "tableau", None)
    if stages is None and isinstance(tableau, diffrax.ButcherTableau):
        stages = len(tableau.c) + 1
    if stages is not None and (isinstance(stages, bool) or int(stages) != stages or stages < 1):
        raise ValueError(f"stages must be a positive integer or None, got {stages!r}")
    evaluations = None
    if isinstance(instance, diffrax.AbstractERK) and isinstance(tableau, diffrax.ButcherTableau):
        evaluations = len(tableau.c) if tableau.fsal else len(tableau.c) + 1
    elif isinstance(instance, diffrax.Euler):
        evaluations = 1
    if implicit is None:
        implicit = isinstance(instance, diffrax.AbstractImplicitSolver)
    if error_estimate is None:
        error_estimate = has_error_estimate(instance)
    if stepsize_controller is None:
        stepsize_controller = _adaptive(1e-6, 1e-9) if error_estimate else diffrax.ConstantStepSize
    preset = SolverPreset(
        key, make_solver, int(order), None if stages is None else int(stages), evaluations, bool(implicit),
        bool(error_estimate), stepsize_controller, None, description,
    )
    _REGISTRY[key] = preset
    return preset


def unregister_solver(name: str) -> None:
    """Remove a preset added by `register_solver` (the built-in ones stay)."""
    key = name.lower()
    if key in _BUILTIN_NAMES:
        raise ValueError(f"{key!r} is a built-in preset and cannot be removed")
    if key not in _REGISTRY:
        raise ValueError(f"no solver preset {name!r}; registered: {SOLVER_PRESETS}")
    del _REGISTRY[key]


_BUILTIN_NAMES = frozenset(_REGISTRY)


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


def describe_solver(solver: "str | diffrax.AbstractSolver | type[diffrax.AbstractSolver]") -> SolverPreset:
    """The `SolverPreset` of a preset name, or a record of the same facts about a solver.

    For a solver object (or a solver class, built with no arguments) that is no preset,
    the facts are read from the solver: its `name` is its class name, its `order` what
    diffrax's `solver.order(terms)` says (`0` where it says nothing), its stages from its
    Butcher tableau, its default controller `PIDController(rtol=1e-6, atol=1e-9)` if it
    has an error estimate, else `ConstantStepSize`.
    """
    if isinstance(solver, str):
        key = solver.lower()
        if key not in _REGISTRY:
            raise ValueError(f"solver must be one of {SOLVER_PRESETS} or a diffrax solver, got {solver!r}")
        return _REGISTRY[key]
    if isinstance(solver, type) and issubclass(solver, diffrax.AbstractSolver):
        try:
            solver = solver()
        except TypeError as error:
            raise TypeError(
                f"the solver class {solver.__name__} cannot be built with no arguments ({error}); "
                "pass a solver instance instead"
            ) from None
    if not isinstance(solver, diffrax.AbstractSolver):
        raise TypeError(f"solver must be a diffrax solver or one of {SOLVER_PRESETS}, got {solver!r}")
    for preset in _REGISTRY.values():
        # A registered solver object is described by its record (and its name).
        if preset.make_fixed_step_solver is None and type(solver) is type(preset.make_solver()):
            if eqx.tree_equal(solver, preset.make_solver()) is True:
                return preset
    term = diffrax.ODETerm(lambda t, y, args: -y)
    try:
        order = solver.order(term)
    except Exception:  # a solver whose order depends on terms it has not been given
        order = None
    tableau = getattr(solver, "tableau", None)
    stages = len(tableau.c) + 1 if isinstance(tableau, diffrax.ButcherTableau) else None
    evaluations = None
    if isinstance(solver, diffrax.AbstractERK) and isinstance(tableau, diffrax.ButcherTableau):
        evaluations = len(tableau.c) if tableau.fsal else len(tableau.c) + 1
    elif isinstance(solver, diffrax.Euler):
        evaluations = 1
    estimate = has_error_estimate(solver)
    instance = solver
    return SolverPreset(
        type(solver).__name__, lambda: instance, int(order) if order else 0, stages, evaluations,
        isinstance(solver, diffrax.AbstractImplicitSolver), estimate,
        _adaptive(1e-6, 1e-9) if estimate else diffrax.ConstantStepSize,
    )


def solver_from_spec(spec: str) -> "str | diffrax.AbstractSolver":
    """The solver a command line names: a preset name, or `module:attribute`.

    `module:attribute` imports `module` (from `sys.path`, so the current directory and
    `PYTHONPATH` count) and takes `attribute`: a diffrax solver instance, or a solver class
    built with no arguments (`diffrax:Bosh3`, `my_methods:RALSTON3`). Returns the preset
    name (lower case) or the solver instance.
    """
    if not isinstance(spec, str) or not spec:
        raise ValueError(f"solver must be a preset name or 'module:attribute', got {spec!r}")
    if ":" not in spec:
        key = spec.lower()
        if key not in _REGISTRY:
            raise ValueError(
                f"unknown solver {spec!r}: give a preset ({', '.join(SOLVER_PRESETS)}) or "
                "'module:attribute' naming a diffrax solver, e.g. 'diffrax:Bosh3'"
            )
        return key
    module_name, _, attribute = spec.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as error:
        raise ValueError(f"solver {spec!r}: cannot import module {module_name!r} ({error})") from None
    value = module
    for part in attribute.split("."):
        try:
            value = getattr(value, part)
        except AttributeError:
            raise ValueError(f"solver {spec!r}: module {module_name!r} has no attribute {attribute!r}") from None
    if isinstance(value, type) and issubclass(value, diffrax.AbstractSolver):
        try:
            value = value()
        except TypeError as error:
            raise ValueError(
                f"solver {spec!r}: the class {value.__name__} cannot be built with no arguments ({error}); "
                "name an instance instead"
            ) from None
    if not isinstance(value, diffrax.AbstractSolver):
        raise ValueError(f"solver {spec!r} names {value!r}, which is no diffrax solver (instance or class)")
    return value


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

    def _term_and_first_step(self, vector_field, dt, projection, velocity_indices):
        """The term to solve and the first step `integrate` and `dense_states` both take."""
        # An adaptive controller picks its own first step (Hairer's heuristic). A first
        # trial step of the whole `dt` can overflow on a stiff problem, and the
        # PIDController turns the resulting NaN error into a NaN step size that rejects
        # every later step (Van der Pol, mu=1e3, dt=10: 0 of 4096 steps accepted).
        dt0 = dt / self.substeps if isinstance(self.stepsize_controller, diffrax.ConstantStepSize) else None
        if projection is None and velocity_indices is None:
            return diffrax.ODETerm(vector_field), dt0
        optional = {} if projection is None else {"projection": projection}
        return ProjectedODETerm(vector_field, velocity_indices=velocity_indices, **optional), dt0

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
        term, dt0 = self._term_and_first_step(vector_field, dt, projection, velocity_indices)
        if self._single_step:
            return self._step_once(term, y0, u, dt, projection)
        solution = self._solve(term, y0, u, dt, dt0, adjoint=self.adjoint)
        steps: IntScalar = solution.stats["num_accepted_steps"]
        rejected: IntScalar = solution.stats["num_steps"] - steps
        solved = solution.result == diffrax.RESULTS.successful
        return self._finish(solution.ys[-1], solved, steps, rejected, projection)

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
    ) -> tuple[Array, BoolScalar]:
        """The solver's own dense output of the solve `integrate` makes, at times `ts` in `[0, dt]`.

        Same solver, controller, first step and budget as `integrate`, so the same steps;
        between them the solver's interpolation (Hermite for the plain Runge--Kutta
        methods, the methods' own for Tsit5, Dopri5, Dopri8). No projection is applied to
        the interpolated states. Returns the states, shape `(len(ts), n)`, and whether the
        solve succeeded.
        """
        dt = jnp.asarray(dt, dtype=y0.dtype)
        term, dt0 = self._term_and_first_step(vector_field, dt, projection, velocity_indices)
        solution = self._solve(term, y0, u, dt, dt0, saveat=diffrax.SaveAt(ts=jnp.asarray(ts, dtype=y0.dtype)))
        return solution.ys, solution.result == diffrax.RESULTS.successful

    def _solve(self, term, y0, u, dt, dt0, **options) -> diffrax.Solution:
        """`diffeqsolve` over `[0, dt]` with this integrator's solver, controller and budget."""
        controller = self.stepsize_controller
        if type(controller) is diffrax.PIDController:
            controller = GuardedPIDController(**{f.name: getattr(controller, f.name) for f in dataclasses.fields(controller)})
        return diffrax.diffeqsolve(
            term, self.solver, t0=jnp.zeros((), dtype=y0.dtype), t1=dt, dt0=dt0, y0=y0, args=u,
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
        if key not in _REGISTRY:
            raise ValueError(f"solver must be one of {SOLVER_PRESETS} or a diffrax solver, got {solver!r}")
        preset = _REGISTRY[key]
        if stepsize_controller is None:
            stepsize_controller = preset.make_controller()
        adaptive = isinstance(stepsize_controller, diffrax.AbstractAdaptiveStepSizeController)
        if preset.make_fixed_step_solver is not None and not adaptive:
            solver = preset.make_fixed_step_solver()
        else:
            solver = preset.make_solver()
    return Integrator(
        solver, stepsize_controller, max_steps=max_steps, adjoint=adjoint, substeps=substeps
    )
