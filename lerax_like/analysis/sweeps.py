"""The solver settings of a work-precision study: a solver and the steps or tolerances it runs at.

`SolverSweep` is one line of a work-precision diagram; `default_sweeps` the study's own
set (every order from 1 to 8, or the implicit presets on a stiff scene); `sweeps_for`
the settings of solvers a user names (`lerax-like study --solver NAME`).
"""

import dataclasses
from collections.abc import Sequence
from typing import Any

import diffrax
import jax.numpy as jnp

from ..integrate import Integrator, describe_solver, make_integrator


@dataclasses.dataclass(frozen=True)
class SolverSweep:
    """One line of a work-precision diagram: a solver and the settings it is run at.

    - `solver`: a preset name of `make_integrator` (`"euler"`, `"rk4"`, `"tsit5"`, or one
      added by `register_solver`), a diffrax solver, or a diffrax solver class (built with
      no arguments).
    - `substeps`: constant-step runs, `substeps` equal steps per env step (step size
      `env.dt / substeps`).
    - `tolerances`: adaptive runs with `PIDController(rtol, atol)`, one per pair.
    - `name`: how the outputs name the solver (default: the preset's name, or the
      solver's class name).

    Give exactly one of `substeps` and `tolerances`.
    """

    solver: "str | diffrax.AbstractSolver"
    substeps: tuple[int, ...] = ()
    tolerances: tuple[tuple[float, float], ...] = ()
    name: str = ""

    def __post_init__(self):
        description = describe_solver(self.solver)  # checks the solver; builds a class
        if isinstance(self.solver, str):
            object.__setattr__(self, "solver", description.name)
        elif isinstance(self.solver, type):
            object.__setattr__(self, "solver", description.make_solver())
        if not self.name:
            object.__setattr__(self, "name", description.name)
        object.__setattr__(self, "substeps", tuple(self.substeps))
        object.__setattr__(self, "tolerances", tuple(tuple(pair) for pair in self.tolerances))
        if bool(self.substeps) == bool(self.tolerances):
            raise ValueError(f"SolverSweep({self.name!r}): give exactly one of substeps and tolerances")
        if any(int(k) != k or k < 1 for k in self.substeps):
            raise ValueError(f"SolverSweep({self.name!r}): substeps must be positive integers, got {self.substeps}")
        if any(not (r > 0 and a > 0) for r, a in self.tolerances):
            raise ValueError(f"SolverSweep({self.name!r}): rtol and atol must be > 0, got {self.tolerances}")
        if self.tolerances and not description.error_estimate:
            raise ValueError(
                f"SolverSweep({self.name!r}): the solver has no error estimate, so it cannot be swept over "
                "tolerances; sweep it over substeps"
            )

    @property
    def description(self):
        """The solver's `SolverPreset` record: order, stages, error estimate (`describe_solver`)."""
        return describe_solver(self.solver)

    @property
    def adaptive(self) -> bool:
        return bool(self.tolerances)

    @property
    def label(self) -> str:
        return f"{self.name} (PID)" if self.adaptive else self.name

    def record(self) -> dict[str, Any]:
        """The sweep for a JSON record: the solver by name (and by its `repr` if no preset)."""
        entry: dict[str, Any] = {"name": self.name, "order": self.description.order or None}
        entry["solver"] = self.solver if isinstance(self.solver, str) else repr(self.solver)
        entry["substeps"] = list(self.substeps)
        entry["tolerances"] = [list(pair) for pair in self.tolerances]
        return entry

    def integrators(self, *, max_steps: int | None = None) -> list[tuple[dict[str, Any], Integrator]]:
        """`(setting, integrator)` for every setting of the sweep; `max_steps` per env step."""
        if self.adaptive:
            # Tolerances as arrays, not Python floats: they are then traced leaves, and
            # one compilation serves the whole tolerance sweep.
            return [
                (
                    {"rtol": rtol, "atol": atol, "substeps": None},
                    make_integrator(
                        self.solver,
                        diffrax.PIDController(rtol=jnp.asarray(rtol), atol=jnp.asarray(atol)),
                        max_steps=max_steps,
                    ),
                )
                for rtol, atol in self.tolerances
            ]
        return [
            (
                {"rtol": None, "atol": None, "substeps": k},
                make_integrator(self.solver, diffrax.ConstantStepSize(), substeps=k, max_steps=max_steps),
            )
            for k in self.substeps
        ]


def with_substeps(sweeps: Sequence[SolverSweep], substeps: Sequence[int]) -> tuple[SolverSweep, ...]:
    """`sweeps` with every fixed-step sweep run at `substeps` instead (`--substeps`); the
    adaptive ones unchanged. `ValueError` (naming `substeps`) for a count that is no
    positive integer."""
    if not substeps or any(int(k) != k or k < 1 for k in substeps):
        raise ValueError(f"substeps must be positive integers, got {list(substeps)}")
    steps = tuple(sorted(set(int(k) for k in substeps)))
    return tuple(sweep if sweep.adaptive else dataclasses.replace(sweep, substeps=steps) for sweep in sweeps)


def _powers_of_two(n: int) -> tuple[int, ...]:
    return tuple(2**i for i in range(n))


def tolerance_pairs(exponents: Sequence[int]) -> tuple[tuple[float, float], ...]:
    """`(rtol, atol)` pairs `(10**-e, 10**-(e + 3))`: DiffEqDevTools' convention, atol three
    orders below rtol."""
    return tuple((10.0**-e, 10.0 ** -(e + 3)) for e in exponents)


def _substeps_for_order(order: int, *, quick: bool) -> tuple[int, ...]:
    # At CartPole's dt = 0.02 these put a method's errors between about 1e-2 and the
    # reference floor (an unknown order is taken as 3).
    if quick:
        return {1: (16, 64, 256), 2: (2, 8, 32)}.get(order, (1, 2, 4))
    return _powers_of_two({1: 11, 2: 8, 3: 6, 4: 6}.get(order, 4))


def sweeps_for(
    solvers: Sequence["str | diffrax.AbstractSolver"], *, quick: bool = False, stiff: bool = False
) -> tuple[SolverSweep, ...]:
    """The sweeps of `lerax-like study --solver NAME ...`: every solver at default settings.

    A solver without an error estimate is swept over substeps (more of them for a lower
    order); one with an estimate over substeps and over tolerances, or, on a stiff scene
    (where a fixed step small enough for stability is no comparison), over tolerances only.
    """
    exponents = [4, 7, 9, 11] if quick else list(range(4, 13))
    sweeps = []
    names: dict[str, int] = {}
    for solver in solvers:
        description = describe_solver(solver)
        name = description.name
        if name in names:  # two solvers of one class: tell them apart
            names[name] += 1
            name = f"{name}#{names[name]}"
        else:
            names[name] = 1
        if not (stiff and description.error_estimate):
            sweeps.append(SolverSweep(solver, substeps=_substeps_for_order(description.order, quick=quick), name=name))
        if description.error_estimate:
            sweeps.append(SolverSweep(solver, tolerances=tolerance_pairs(exponents), name=name))
    return tuple(sweeps)


def default_sweeps(*, quick: bool = False, stiff: bool = False) -> tuple[SolverSweep, ...]:
    """The solvers and settings of `lerax-like study`: every order from 1 to 8.

    On a stiff scene (`stiff`): the implicit presets against Tsit5, over tolerances.
    """
    if stiff:
        if quick:
            return (
                SolverSweep("tsit5", tolerances=tolerance_pairs([4, 6])),
                SolverSweep("kvaerno3", tolerances=tolerance_pairs([4, 6])),
                SolverSweep("kvaerno5", tolerances=tolerance_pairs([4, 6, 8])),
            )
        return (
            SolverSweep("tsit5", tolerances=tolerance_pairs([4, 6, 8])),
            SolverSweep("implicit_euler", tolerances=tolerance_pairs([2, 3, 4, 5])),
            SolverSweep("kvaerno3", tolerances=tolerance_pairs(range(4, 10))),
            SolverSweep("kvaerno4", tolerances=tolerance_pairs(range(4, 11))),
            SolverSweep("kvaerno5", tolerances=tolerance_pairs(range(4, 12))),
        )
    if quick:
        # Each substep count is a separate compilation (substeps shape the solve), so
        # the quick study keeps few: enough for Euler's and RK4's orders below 1e-2.
        return (
            SolverSweep("euler", substeps=(16, 64, 256)),
            SolverSweep("rk4", substeps=(1, 2, 4)),
            SolverSweep("tsit5", tolerances=tolerance_pairs([4, 7, 9, 11])),
        )
    return (
        SolverSweep("euler", substeps=_powers_of_two(11)),
        SolverSweep("heun", substeps=_powers_of_two(8)),
        SolverSweep("midpoint", substeps=_powers_of_two(8)),
        SolverSweep("rk4", substeps=_powers_of_two(6)),
        SolverSweep("tsit5", substeps=_powers_of_two(4)),
        SolverSweep("tsit5", tolerances=tolerance_pairs(range(4, 13))),
        SolverSweep("dopri5", tolerances=tolerance_pairs(range(4, 13))),
        SolverSweep("dopri8", tolerances=tolerance_pairs(range(4, 13))),
    )
