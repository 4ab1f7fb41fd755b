"""Work-precision studies: error against cost for every solver setting, on a real scene.

A study takes a scene, a batch of initial states, action schedules, a horizon in env
steps, and solver sweeps (substeps for fixed-step solvers, paired `rtol`/`atol` for
adaptive ones) of any solver: a preset name, a diffrax solver, or a solver registered
with `lerax_like.register_solver`. For each setting it integrates the batch through the
env's own step (`env.evolve` over `[0, dt]` per env step, the input held), and measures

- the error against an independent SciPy reference, at the final time and maximal over
  the env-step ends (max norm over state components and initial states);
- the dense errors, as DiffEqDevTools' `L2` and `Linf`: root mean square and maximum over
  a grid of `dense_points` times per env step (its end included), from the solver's own
  dense output against the reference's (`solve_ivp(dense_output=True)`);
- the run time of the whole batch under `vmap` (compiled first, `block_until_ready`,
  minimum of repeats);
- solver steps and vector-field evaluations, the machine-independent cost;
- for zero input, the drift of the energy and momentum of the dynamics (maximum over
  the trajectory).
"""

import dataclasses
import math
import time
from collections.abc import Sequence
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..env import AbstractEnv, EnvState
from ..integrate import Integrator, describe_solver, make_integrator, solver_facts
from ..spaces import Box, Discrete
from .reference import dense_reference_trajectories
from .scenes import SCENES, make_scene, reference_method


SCHEDULES = ("zero", "constant", "recorded")


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


@dataclasses.dataclass(frozen=True)
class StudyConfig:
    """Everything a study depends on; `to_json` records it so a study can be rerun.

    - `scene`, `scene_kwargs`: the env, by its name in `SCENES`, and its keywords.
    - `sweeps`: the solver settings (`default_sweeps()` if empty).
    - `schedules`: action schedules, each a separate set of rows: `"zero"` (no input:
      a conservative setting where energy and momentum drifts are reported),
      `"constant"` (`constant_action` held throughout) and `"recorded"` (`actions`, or
      a seeded random sequence from the action space).
    - `horizon`: env steps per trajectory; `batch`: initial states, drawn from
      `env.initial` with `seed` unless `initial_states` is given.
    - `repeats`: timed runs per setting, after one compiling run; the minimum is kept.
    - `reference_method`: SciPy method (`None`: DOP853, Radau for scenes in
      `stiff`); `reference_tolerance`: its `rtol = atol`. The reference floor is
      estimated by a second solve at ten times the tolerance, and optionally
      (`check_method`) by an independent method.
    - `fit_ceiling`: convergence orders are fitted to errors below it (and above the
      reference floor).
    - `dense_points`: the dense error grid has this many points per env step (its end
      and `dense_points - 1` inside), where the solver's own dense output is compared
      with the reference's (`l2_error`, `linf_error`).
    - `max_steps`: solver steps allowed per env step (default: the integrator's, 4096
      for adaptive runs).
    """

    scene: str = "CartPole"
    scene_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    sweeps: tuple[SolverSweep, ...] = ()
    schedules: tuple[str, ...] = ("recorded", "zero")
    horizon: int = 100
    batch: int = 8
    repeats: int = 5
    seed: int = 0
    initial_states: Any = None
    actions: Any = None
    constant_action: Any = None
    reference_method: str | None = None
    reference_tolerance: float = 1e-13
    check_method: str | None = None
    fit_ceiling: float = 1e-2
    dense_points: int = 8
    max_steps: int | None = None

    def __post_init__(self):
        unknown = set(self.schedules) - set(SCHEDULES)
        if unknown or not self.schedules:
            raise ValueError(f"schedules must be a non-empty subset of {SCHEDULES}, got {self.schedules}")
        for name in ("horizon", "batch", "repeats", "dense_points"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not self.reference_tolerance > 0:
            raise ValueError(f"reference_tolerance must be > 0, got {self.reference_tolerance}")

    @classmethod
    def default(cls, scene: str = "CartPole", *, quick: bool = False, **overrides) -> "StudyConfig":
        """The study `lerax-like study SCENE [--quick]` runs.

        On a stiff scene (Van der Pol), the classic stiff test: `mu = 1e3` over
        `[0, 3000]` (100 env steps of 30), random forces, the implicit presets against
        Tsit5 (`default_sweeps(stiff=True)`).
        """
        stiff = SCENES[scene].stiff if scene in SCENES else False
        settings: dict[str, Any] = dict(scene=scene, sweeps=default_sweeps(quick=quick, stiff=stiff))
        if stiff:
            # The Radau reference at 1e-13 takes about a minute per initial state here.
            settings.update(
                scene_kwargs=dict(mu=1e3, dt=30.0), schedules=("recorded",), horizon=100, max_steps=100_000,
                batch=1 if quick else 2, repeats=1 if quick else 3,
            )
        elif quick:
            settings.update(horizon=50, batch=4, repeats=3)
        settings.update(overrides)
        return cls(**settings)

    @property
    def method(self) -> str:
        if self.reference_method is not None:
            return self.reference_method
        return reference_method(self.scene)


def _trajectory(env: AbstractEnv, y0, inputs):
    # The env's own integration (`evolve`, the core of every env step), with the physical
    # input given directly, so that a zero force can be studied on a scene whose actions
    # cannot express one (CartPole pushes left or right).
    def body(state, u):
        next_state, info = env.evolve(state, u)
        outputs = (next_state.y, info["solver_ok"], info["solver_steps"], info["solver_rejected_steps"])
        return next_state, outputs

    state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
    _, (ys, ok, steps, rejected) = jax.lax.scan(body, state, inputs)
    return ys, ok, steps, rejected


@eqx.filter_jit
def _batched_trajectories(env: AbstractEnv, y0s, inputs):
    return jax.vmap(_trajectory, in_axes=(None, 0, None))(env, y0s, inputs)


def evaluations_per_step(solver: diffrax.AbstractSolver) -> tuple[int, int, int] | None:
    """`(per accepted step, per rejected step, once per solve)` vector-field evaluations,
    as `lerax_like.solver_facts` counts them; `None` for implicit solvers, whose count
    depends on the root finder."""
    facts = solver_facts(solver)
    if facts.evaluations_per_step is None:
        return None
    return facts.evaluations_per_step, facts.evaluations_per_rejected_step, facts.evaluations_per_solve


@eqx.filter_jit
def _batched_dense_states(env: AbstractEnv, starts, inputs, ts):
    """The solver's dense output inside every env step, shape `(B, T, len(ts), n)`.

    Env step `k` of trajectory `b` restarts from `starts[b, k]`, the solver's own state
    after the step before, as the trajectory did (`env.evolve`): the same solve, saved
    inside.
    """
    physics = env.physics

    def one_step(y0, u):
        return env.integrator.dense_states(
            physics.vector_field, y0, u, env.dt, ts,
            projection=env.project if env.projects_state() else None,
            velocity_indices=physics.velocity_indices,
        )

    def trajectory(y_starts):
        return jax.lax.map(lambda args: one_step(*args), (y_starts, inputs))

    return jax.vmap(trajectory)(starts)


def _dense_errors(env, y0s, ys: np.ndarray, inputs, fractions: np.ndarray, entry) -> dict[str, float] | None:
    """`l2_error` and `linf_error` over the dense grid: every env-step end and the points inside.

    As DiffEqDevTools' `L2` and `Linf`: the root mean square (over grid points and state
    components) and the maximum of the error; each maximal over the batch. The step ends
    are the trajectory's own states, so `linf_error >= max_error`.
    """
    dt = float(env.dt)
    if len(fractions) == 0:
        inside_errors = np.zeros(ys.shape[:2] + (0, ys.shape[-1]))
    else:
        starts = np.concatenate([np.asarray(y0s)[:, None], ys[:, :-1]], axis=1)
        states, ok = _batched_dense_states(env, jnp.asarray(starts), inputs, jnp.asarray(fractions * dt))
        if not bool(np.all(np.asarray(ok))):
            return None
        inside_errors = np.asarray(states) - entry["reference_inside"]  # (B, T, m - 1, n)
    boundary_errors = ys - entry["reference"]  # (B, T, n)
    grid = np.concatenate([inside_errors, boundary_errors[:, :, None]], axis=2)  # (B, T, m, n)
    squared = np.mean(grid.reshape(grid.shape[0], -1) ** 2, axis=1)
    return {"l2_error": float(np.sqrt(np.max(squared))), "linf_error": float(np.max(np.abs(grid)))}


def _empty_call_seconds(y0s, repeats: int = 20) -> float:
    """The time of a compiled call that does nothing: a timing below a few of these is unresolved."""
    identity = jax.jit(lambda y: y)
    jax.block_until_ready(identity(y0s))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(identity(y0s))
        times.append(time.perf_counter() - start)
    return min(times)


def _controller_name(integrator: Integrator) -> str:
    return type(integrator.stepsize_controller).__name__


def _schedule_inputs(env, config: StudyConfig, schedule: str, key) -> tuple[np.ndarray, np.ndarray | None]:
    """`(inputs (T, m), actions or None)` of an action schedule."""
    space = env.action_space
    sample = space.sample(key=key)
    if schedule == "zero":
        u = jnp.zeros_like(env.physical_input(sample))
        return np.repeat(np.asarray(u)[None], config.horizon, axis=0), None
    if schedule == "constant":
        if config.constant_action is not None:
            action = jnp.asarray(config.constant_action)
        elif isinstance(space, Discrete):
            action = jnp.asarray(space.n - 1)
        elif isinstance(space, Box):
            action = 0.5 * jnp.broadcast_to(space.high, space.shape)
        else:
            raise ValueError(f"give constant_action for a scene with action space {space}")
        actions = jnp.broadcast_to(action, (config.horizon,) + action.shape)
    else:
        if config.actions is not None:
            actions = jnp.asarray(config.actions)
            if actions.shape[0] != config.horizon:
                raise ValueError(f"actions has {actions.shape[0]} steps, horizon is {config.horizon}")
        else:
            actions = jax.vmap(lambda k: space.sample(key=k))(jr.split(key, config.horizon))
    inputs = jax.vmap(env.physical_input)(actions)
    return np.asarray(inputs), np.asarray(actions)


def _invariant_drifts(dynamics, ys: np.ndarray, y0s: np.ndarray) -> dict[str, float]:
    """Maximum over trajectory and batch of `|I(y_t) - I(y_0)|` for energy and momentum."""
    drifts = {}
    for name in ("energy", "momentum"):
        invariant = getattr(dynamics, name, None)
        if invariant is None:
            continue
        along = np.asarray(jax.vmap(jax.vmap(invariant))(jnp.asarray(ys)))
        start = np.asarray(jax.vmap(invariant)(jnp.asarray(y0s)))
        drifts[f"{name}_drift"] = float(np.max(np.abs(along - start[:, None])))
    return drifts


@dataclasses.dataclass
class StudyResult:
    """The rows of a study (one per schedule and setting) and what produced them.

    `config` is the `StudyConfig`; `run_gradient_study` returns one too, with its
    `GradientStudyConfig` (both have the `fit_ceiling` the orders are fitted below).
    """

    config: Any
    rows: list[dict[str, Any]]
    record: dict[str, Any]

    def convergence_orders(self) -> list[dict[str, Any]]:
        """Fitted slopes of log error on log step size, per schedule and fixed-step solver."""
        from .convergence import convergence_orders

        return convergence_orders(self.rows, ceiling=self.config.fit_ceiling)


def run_study(config: StudyConfig, *, progress: bool = True) -> StudyResult:
    """Run `config` (in float64) and return its rows; see the module docstring."""
    with jax.enable_x64(True):
        return _run_study(config, progress=progress)


def _progress_bar(total: int, enabled: bool, description: str):
    if enabled:
        try:
            from tqdm.auto import tqdm
        except ImportError:  # progress bars are optional: pip install 'lerax_like[study]'
            pass
        else:
            return tqdm(total=total, desc=description, leave=False)
    return None


def _run_study(config: StudyConfig, *, progress: bool) -> StudyResult:
    env = make_scene(config.scene, **config.scene_kwargs)
    sweeps = config.sweeps or default_sweeps()
    initial_key, schedule_key = jr.split(jr.key(config.seed))
    if config.initial_states is None:
        y0s = jax.vmap(lambda k: env.initial(key=k).y)(jr.split(initial_key, config.batch))
    else:
        y0s = jnp.asarray(config.initial_states, dtype=jnp.float64)
        if y0s.ndim != 2:
            raise ValueError(f"initial_states must have shape (batch, n), got {y0s.shape}")
    y0s_np = np.asarray(y0s, dtype=np.float64)
    dt = float(env.dt)
    method, tolerance = config.method, config.reference_tolerance
    # The dense error grid inside each env step (its end is the step's boundary).
    fractions = np.arange(1, config.dense_points) / config.dense_points

    # One reference per schedule, with its floor.
    schedules: dict[str, dict[str, Any]] = {}
    for schedule, key in zip(config.schedules, jr.split(schedule_key, len(config.schedules))):
        inputs, actions = _schedule_inputs(env, config, schedule, key)
        start = time.perf_counter()
        reference, reference_inside = dense_reference_trajectories(
            env.physics, y0s_np, inputs, dt, fractions, method=method, rtol=tolerance, atol=tolerance
        )
        reference_seconds = time.perf_counter() - start
        looser, looser_inside = dense_reference_trajectories(
            env.physics, y0s_np, inputs, dt, fractions, method=method, rtol=10 * tolerance, atol=10 * tolerance
        )
        entry = {
            "inputs": inputs,
            "actions": actions,
            "reference": reference,
            "reference_inside": reference_inside,
            "reference_seconds": reference_seconds,
            # The reference at ten times its tolerance differs from the truth by more
            # than the reference does: a conservative bound on the reference's error.
            "reference_floor": float(np.max(np.abs(looser - reference))),
            # The same over the dense grid: the floor of `linf_error`.
            "dense_reference_floor": float(
                max(np.max(np.abs(looser - reference)), np.max(np.abs(looser_inside - reference_inside), initial=0.0))
            ),
        }
        if config.check_method is not None:
            check, check_inside = dense_reference_trajectories(
                env.physics, y0s_np, inputs, dt, fractions, method=config.check_method, rtol=tolerance, atol=tolerance
            )
            entry["check_discrepancy"] = float(np.max(np.abs(check - reference)))
            entry["dense_check_discrepancy"] = float(
                max(entry["check_discrepancy"], np.max(np.abs(check_inside - reference_inside), initial=0.0))
            )
        if schedule == "zero":
            entry["reference_drifts"] = _invariant_drifts(env.physics, reference, y0s_np)
        schedules[schedule] = entry

    timing_floor = _empty_call_seconds(y0s)
    settings = [
        (sweep, setting, integrator)
        for sweep in sweeps
        for setting, integrator in sweep.integrators(max_steps=config.max_steps)
    ]
    bar = _progress_bar(len(settings), progress, f"study {config.scene}")
    rows: list[dict[str, Any]] = []
    for sweep, setting, integrator in settings:
        # The env as a user would set it up with this solver.
        study_env = eqx.tree_at(lambda e: e.integrator, env, integrator)
        per_step = evaluations_per_step(integrator.solver)
        for schedule, entry in schedules.items():
            inputs = jnp.asarray(entry["inputs"])
            outputs = _batched_trajectories(study_env, y0s, inputs)  # compiles
            jax.block_until_ready(outputs)
            times = []
            for _ in range(config.repeats):
                start = time.perf_counter()
                outputs = jax.block_until_ready(_batched_trajectories(study_env, y0s, inputs))
                times.append(time.perf_counter() - start)
            ys, ok, steps, rejected = (np.asarray(x) for x in outputs)
            solver_ok = bool(np.all(ok))
            deviation = np.max(np.abs(ys - entry["reference"]), axis=-1)  # (B, T)
            dense = _dense_errors(study_env, y0s, ys, inputs, fractions, entry) if solver_ok else None
            accepted_per_trajectory = float(np.mean(np.sum(steps, axis=1)))
            attempted_per_trajectory = accepted_per_trajectory + float(np.mean(np.sum(rejected, axis=1)))
            if per_step is None:
                evaluations = math.nan
            else:
                per_accepted, per_rejected, per_solve = per_step
                evaluations = (
                    accepted_per_trajectory * per_accepted
                    + (attempted_per_trajectory - accepted_per_trajectory) * per_rejected
                    + config.horizon * per_solve
                )
            row = {
                "scene": config.scene,
                "schedule": schedule,
                "solver": sweep.name,
                "label": sweep.label,
                "order": sweep.description.order or math.nan,
                "controller": _controller_name(integrator),
                "dt": dt / setting["substeps"] if setting["substeps"] is not None else math.nan,
                "env_dt": dt,
                "substeps": setting["substeps"] if setting["substeps"] is not None else "",
                "rtol": setting["rtol"] if setting["rtol"] is not None else math.nan,
                "atol": setting["atol"] if setting["atol"] is not None else math.nan,
                "error": float(np.max(deviation[:, -1])) if solver_ok else math.nan,
                "max_error": float(np.max(deviation)) if solver_ok else math.nan,
                "l2_error": dense["l2_error"] if dense else math.nan,
                "linf_error": dense["linf_error"] if dense else math.nan,
                "seconds": min(times),
                "seconds_spread": (float(np.median(times)) - min(times)) / min(times),
                "timing_floor": timing_floor,
                "steps": accepted_per_trajectory,
                "attempted_steps": attempted_per_trajectory,
                "rejected_steps": attempted_per_trajectory - accepted_per_trajectory,
                "vector_field_evaluations": evaluations,
                "energy_drift": math.nan,
                "momentum_drift": math.nan,
                "solver_ok": solver_ok,
                "batch": int(y0s.shape[0]),
                "horizon": config.horizon,
                "dtype": str(ys.dtype),
                "reference_method": method,
                "reference_tolerance": tolerance,
                "reference_floor": entry["reference_floor"],
                "dense_points": config.dense_points,
            }
            if schedule == "zero" and solver_ok:
                row.update(_invariant_drifts(env.physics, ys, y0s_np))
            rows.append(row)
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()

    record = {
        "config": _config_record(config, sweeps),
        "initial_states": y0s_np.tolist(),
        "dt": dt,
        "horizon_seconds": config.horizon * dt,
        "schedules": {
            name: {
                "inputs": entry["inputs"].tolist(),
                "actions": None if entry["actions"] is None else entry["actions"].tolist(),
                "reference_seconds": entry["reference_seconds"],
                "reference_floor": entry["reference_floor"],
                "dense_reference_floor": entry["dense_reference_floor"],
                **({"check_method": config.check_method, "check_discrepancy": entry["check_discrepancy"],
                    "dense_check_discrepancy": entry["dense_check_discrepancy"]}
                   if "check_discrepancy" in entry else {}),
                **({"reference_drifts": entry["reference_drifts"]} if "reference_drifts" in entry else {}),
            }
            for name, entry in schedules.items()
        },
        "reference": {
            "library": "scipy.integrate.solve_ivp",
            "method": method,
            "rtol": tolerance,
            "atol": tolerance,
            "floor_estimate": f"max |reference(tol) - reference(10 tol)|, same method",
            "dense_output": "solve_ivp(dense_output=True) of the same solves, at the dense grid's inner points",
        },
        "dense_grid": f"{config.dense_points} points per env step: its end and {config.dense_points - 1} equally spaced inside",
        "environment": environment_record(),
    }
    return StudyResult(config=config, rows=rows, record=record)


def _config_record(config: StudyConfig, sweeps) -> dict[str, Any]:
    def plain(value):
        if isinstance(value, (np.ndarray, jax.Array)):
            return np.asarray(value).tolist()
        return value

    return {
        "scene": config.scene,
        "scene_kwargs": {k: plain(v) for k, v in config.scene_kwargs.items()},
        "sweeps": [sweep.record() for sweep in sweeps],
        "schedules": list(config.schedules),
        "horizon": config.horizon,
        "batch": config.batch,
        "repeats": config.repeats,
        "seed": config.seed,
        "initial_states": plain(config.initial_states),
        "actions": plain(config.actions),
        "constant_action": plain(config.constant_action),
        "reference_method": config.method,
        "reference_tolerance": config.reference_tolerance,
        "check_method": config.check_method,
        "fit_ceiling": config.fit_ceiling,
        "dense_points": config.dense_points,
        "max_steps": config.max_steps,
        "dtype": "float64",
    }


def environment_record() -> dict[str, Any]:
    """Library versions and the machine, for the JSON record of a study."""
    import importlib.metadata
    import os
    import platform

    versions = {}
    for package in ("lerax_like", "jax", "jaxlib", "diffrax", "equinox", "numpy", "scipy", "matplotlib"):
        try:
            versions[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            if package == "lerax_like":
                from .. import __version__

                versions[package] = __version__
            else:
                versions[package] = None
    processor = platform.processor()
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    processor = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "python": platform.python_version(),
        "versions": versions,
        "platform": platform.platform(),
        "processor": processor,
        "cpu_count": os.cpu_count(),
        "jax_backend": jax.default_backend(),
        "jax_devices": [str(device) for device in jax.devices()],
    }
