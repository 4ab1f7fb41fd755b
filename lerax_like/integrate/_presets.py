"""Solvers by name: one table of presets, one lookup, one message for a name it does not hold."""

import dataclasses
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Protocol

import diffrax
import equinox as eqx
import numpy as np
import optimistix

from ._facts import solver_facts
from ._rk4 import RK4
from ._root_finder import adaptive_root_finder, fixed_step_root_finder
from ._semi_implicit import SemiImplicitEuler


@dataclasses.dataclass(frozen=True)
class SolverPreset:
    """A solver by name: how to build it, and what a numerical analyst asks of it first.

    - `name`: the name accepted wherever a solver is (`make_integrator(name)`,
      `CartPole(integrator=name)`, `ll.make("CartPole", solver=name)`, `lerax-like study --solver name`).
    - `make_solver`: builds the solver (no arguments).
    - `order`: order of convergence of the method (global error `O(h^order)`).
    - `stages`: stages of one step (`None` if not a Runge--Kutta method);
      `evaluations_per_step`: vector-field evaluations of one accepted step, which is
      `stages - 1` for a first-same-as-last method (`None` for implicit methods).
    - `implicit`: whether a step solves a nonlinear system (diffrax's
      `AbstractImplicitSolver`).
    - `error_estimate`: whether the method has an embedded error estimate, which an
      adaptive controller needs.
    - `make_controller`: the default step-size controller (no arguments).
    - `make_fixed_step_solver`: for implicit methods, the solver to use under a constant
      step size, whose root finder has tolerances of its own (`None`: `make_solver`).
    - `description`: one line, for the listing of `lerax-like solvers`.

    Every fact but `order` is `solver_facts(make_solver())`; build one with `preset`.
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


def adaptive(rtol: float, atol: float) -> Callable[[], diffrax.PIDController]:
    """A function building `PIDController(rtol, atol)`: a preset's default controller."""
    return lambda: diffrax.PIDController(rtol=rtol, atol=atol)


def preset(
    name: str,
    make_solver: Callable[[], diffrax.AbstractSolver],
    *,
    order: int | None = None,
    stages: int | None = None,
    error_estimate: bool | None = None,
    make_controller: Callable[[], diffrax.AbstractStepSizeController] | None = None,
    make_fixed_step_solver: Callable[[], diffrax.AbstractSolver] | None = None,
    description: str = "",
) -> SolverPreset:
    """A `SolverPreset` whose facts are read from the solver (`solver_facts`) unless given.

    The default controller is `PIDController(rtol=1e-6, atol=1e-9)` for a solver with an
    error estimate, else `ConstantStepSize`.
    """
    facts = solver_facts(make_solver())
    order = facts.order if order is None else order
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 1:
        raise ValueError(f"order must be a positive integer, got {order!r}")
    stages = facts.stages if stages is None else stages
    if stages is not None and (isinstance(stages, bool) or int(stages) != stages or stages < 1):
        raise ValueError(f"stages must be a positive integer or None, got {stages!r}")
    error_estimate = facts.error_estimate if error_estimate is None else bool(error_estimate)
    if make_controller is None:
        make_controller = adaptive(1e-6, 1e-9) if error_estimate else diffrax.ConstantStepSize
    return SolverPreset(
        name, make_solver, int(order), None if stages is None else int(stages), facts.evaluations_per_step,
        facts.implicit, error_estimate, make_controller, make_fixed_step_solver, description,
    )


class _ImplicitSolverClass(Protocol):
    """An implicit solver's class (`diffrax.Kvaerno5`), built with a root finder (the abstract
    base's signature, which a type checker would read from `type[AbstractImplicitSolver]`, has none)."""

    def __call__(self, *, root_finder: optimistix.AbstractRootFinder) -> diffrax.AbstractImplicitSolver: ...


def _implicit(name: str, cls: _ImplicitSolverClass, description: str, rtol=1e-6, atol=1e-9):
    return preset(
        name, lambda: cls(root_finder=adaptive_root_finder()), make_controller=adaptive(rtol, atol),
        make_fixed_step_solver=lambda: cls(root_finder=fixed_step_root_finder()), description=description,
    )


def _builtin_presets() -> list[SolverPreset]:
    constant = diffrax.ConstantStepSize
    return [
        preset("euler", diffrax.Euler, description="forward Euler; Gymnasium's CartPole step"),
        preset("heun", diffrax.Heun, make_controller=constant,
               description="Heun's method (explicit trapezoidal), Euler embedded"),
        preset("midpoint", diffrax.Midpoint, make_controller=constant, description="explicit midpoint, Euler embedded"),
        preset("ralston", diffrax.Ralston, make_controller=constant,
               description="Ralston's second-order method, Euler embedded"),
        preset("rk4", RK4, description="classic Runge-Kutta (Kutta 1901)"),
        preset("tsit5", diffrax.Tsit5, description="Tsitouras 5(4), first same as last"),
        preset("dopri5", diffrax.Dopri5, description="Dormand-Prince 5(4), first same as last"),
        preset("dopri8", diffrax.Dopri8, make_controller=adaptive(1e-8, 1e-11),
               description="Dormand-Prince 8(7), first same as last"),
        _implicit("implicit_euler", diffrax.ImplicitEuler, "backward Euler, L-stable", rtol=1e-3, atol=1e-6),
        _implicit("kvaerno3", diffrax.Kvaerno3, "Kvaerno 3(2) ESDIRK, L-stable"),
        _implicit("kvaerno4", diffrax.Kvaerno4, "Kvaerno 4(3) ESDIRK, L-stable"),
        _implicit("kvaerno5", diffrax.Kvaerno5, "Kvaerno 5(4) ESDIRK, L-stable"),
        preset("semi_implicit_euler", SemiImplicitEuler,
               description="symplectic Euler; Gymnasium's Pendulum and MountainCar step"),
    ]


class SolverTable(Mapping[str, SolverPreset]):
    """The solver presets by name, in registration order: the built-in ones and the user's.

    `find(name)` is the one lookup by name (any case), with the one message for a name
    the table does not hold; `names` are the names as they are now.
    """

    def __init__(self, presets: Sequence[SolverPreset]):
        self._presets = {p.name: p for p in presets}
        self.builtin = frozenset(self._presets)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._presets)

    def __getitem__(self, name: str) -> SolverPreset:
        return self._presets[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._presets)

    def __len__(self) -> int:
        return len(self._presets)

    def __repr__(self) -> str:
        return f"SolverTable({', '.join(self._presets)})"

    def find(self, name: str) -> SolverPreset:
        """The preset called `name` (any case); `ValueError` naming every preset if none is."""
        key = name.lower() if isinstance(name, str) else name
        if key not in self._presets:
            raise ValueError(
                f"unknown solver {name!r}: give a preset ({', '.join(self._presets)}), a diffrax solver, or on "
                "the command line 'module:attribute' naming one (e.g. 'diffrax:Bosh3')"
            )
        return self._presets[key]

    def add(self, entry: SolverPreset, *, replace: bool = False) -> None:
        if entry.name in self._presets and not replace:
            raise ValueError(f"a solver preset {entry.name!r} exists already; pass replace=True to replace it")
        self._presets[entry.name] = entry

    def remove(self, name: str) -> None:
        key = self.find(name).name
        if key in self.builtin:
            raise ValueError(f"{key!r} is a built-in preset and cannot be removed")
        del self._presets[key]

    def matching(self, solver: diffrax.AbstractSolver) -> SolverPreset | None:
        """The preset whose solver equals `solver` (a registered instance keeps its name), if any."""
        for entry in self._presets.values():
            if entry.make_fixed_step_solver is None:
                candidate = entry.make_solver()
                if type(solver) is type(candidate) and eqx.tree_equal(solver, candidate) is True:
                    return entry
        return None


SOLVERS = SolverTable(_builtin_presets())
"""Every solver preset by name, the built-in ones and those added by `register_solver`."""


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
    - `stages`, `error_estimate`: default: read from the solver (`solver_facts`).
    - `implicit`: must agree with the solver (`AbstractImplicitSolver`) if given.
    - `stepsize_controller`: function returning the default controller (default:
      `PIDController(rtol=1e-6, atol=1e-9)` with an error estimate, else
      `ConstantStepSize`).
    - `replace`: allow replacing a preset of that name added before (the built-in ones stay).

    Returns the `SolverPreset` added to `SOLVERS`.
    """
    if not isinstance(name, str) or not name or ":" in name or name != name.strip():
        raise ValueError(f"name must be a non-empty string without ':' or surrounding spaces, got {name!r}")
    if isinstance(solver, diffrax.AbstractSolver):
        instance = solver
        make_solver: Callable[[], diffrax.AbstractSolver] = lambda: instance
    elif callable(solver):
        make_solver = solver
        built = solver()
        if not isinstance(built, diffrax.AbstractSolver):
            raise TypeError(f"solver must build a diffrax solver with no arguments; it built {built!r}")
    else:
        raise TypeError(f"solver must be a diffrax solver or a function building one, got {solver!r}")
    entry = preset(
        name.lower(), make_solver, order=order, stages=stages, error_estimate=error_estimate,
        make_controller=stepsize_controller, description=description,
    )
    if implicit is not None and bool(implicit) != entry.implicit:
        raise ValueError(f"implicit={implicit!r}, but the solver {'is' if entry.implicit else 'is not'} implicit")
    SOLVERS.add(entry, replace=replace)
    return entry


def unregister_solver(name: str) -> None:
    """Remove a preset added by `register_solver` (the built-in ones stay)."""
    SOLVERS.remove(name)


def solver_instance(solver: "diffrax.AbstractSolver | type[diffrax.AbstractSolver]") -> diffrax.AbstractSolver:
    """`solver` itself, or the solver a solver class builds with no arguments.

    Raises `TypeError` for anything else, and for a class that needs arguments.
    """
    if isinstance(solver, type) and issubclass(solver, diffrax.AbstractSolver):
        try:
            return solver()
        except TypeError as error:
            raise TypeError(
                f"the solver class {solver.__name__} cannot be built with no arguments ({error}); "
                "pass a solver instance instead"
            ) from None
    if not isinstance(solver, diffrax.AbstractSolver):
        raise TypeError(
            f"{solver!r} is no diffrax solver (an instance, or a class built with no arguments) and no preset "
            f"name ({', '.join(SOLVERS.names)})"
        )
    return solver


def describe_solver(solver: "str | diffrax.AbstractSolver | type[diffrax.AbstractSolver]") -> SolverPreset:
    """The `SolverPreset` of a preset name, or a record of the same facts about a solver.

    For a solver object (or a solver class, built with no arguments) that is no preset,
    the facts are `solver_facts(solver)`: its `name` is its class name, its `order` what
    the solver declares (`0` where it declares nothing), its default controller
    `PIDController(rtol=1e-6, atol=1e-9)` if it has an error estimate, else
    `ConstantStepSize`.
    """
    if isinstance(solver, str):
        return SOLVERS.find(solver)
    solver = solver_instance(solver)
    registered = SOLVERS.matching(solver)
    if registered is not None:
        return registered
    facts = solver_facts(solver)
    instance = solver
    return SolverPreset(
        type(solver).__name__, lambda: instance, facts.order or 0, facts.stages, facts.evaluations_per_step,
        facts.implicit, facts.error_estimate, adaptive(1e-6, 1e-9) if facts.error_estimate else diffrax.ConstantStepSize,
    )
