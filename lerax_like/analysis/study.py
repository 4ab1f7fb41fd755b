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
- for zero input, the drift of the energy (where the scene claims to conserve it) and
  momentum of the dynamics (maximum over the trajectory).

The settings are `SolverSweep`s (`sweeps.py`), the measurements of one setting are in
`measurements.py`, and what the rows conclude (settings that coincide, the cheapest) in
`verdict.py`.
"""

import dataclasses
import math
import time
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..env import AbstractEnv
from ..integrate import Integrator
from ..spaces import Box, Discrete
from .measurements import (
    dense_errors,
    empty_call_seconds,
    evaluations_per_step as evaluations_per_step,
    failure_reason,
    invariant_drifts,
    timed_runs,
)
from .recording import environment_record as environment_record
from .hybrid_reference import hybrid_reference_trajectories
from .friction_reference import friction_reference_trajectories
from .reference import dense_reference_trajectories
from .scenes import SCENES, make_scene, reference_method
from .sweeps import (
    SolverSweep as SolverSweep,
    default_sweeps as default_sweeps,
    sweeps_for as sweeps_for,
    tolerance_pairs as tolerance_pairs,
)


SCHEDULES = ("zero", "constant", "recorded")


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
        Tsit5 (`default_sweeps(stiff=True)`); with `quick`, one initial state over 50 env
        steps and the Radau reference at 1e-11 instead of 1e-13.
        """
        stiff = SCENES[scene].stiff if scene in SCENES else False
        settings: dict[str, Any] = dict(scene=scene, sweeps=default_sweeps(quick=quick, stiff=stiff))
        if stiff:
            # The Radau reference at 1e-13 takes about a minute per initial state here,
            # most of the quick study's time; at 1e-11 its floor is about 3e-11, well
            # below the quick sweep's smallest error (about 2e-7), at a third of the cost.
            settings.update(
                scene_kwargs=dict(mu=1e3, dt=30.0), schedules=("recorded",), horizon=100, max_steps=100_000,
                batch=1 if quick else 2, repeats=1 if quick else 3,
            )
            if quick:
                # [0, 1500]: about one relaxation period (1614 s at mu = 1e3), so one
                # fast transition at least, at half the cost of the reference and of Tsit5.
                settings.update(reference_tolerance=1e-11, horizon=50)
        elif quick:
            settings.update(horizon=50, batch=4, repeats=3)
        settings.update(overrides)
        return cls(**settings)

    @property
    def method(self) -> str:
        if self.reference_method is not None:
            return self.reference_method
        return reference_method(self.scene)


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


def _initial_states(env: AbstractEnv, config: StudyConfig, key) -> np.ndarray:
    if config.initial_states is None:
        y0s = jax.vmap(lambda k: env.initial(key=k).y)(jr.split(key, config.batch))
    else:
        y0s = jnp.asarray(config.initial_states, dtype=jnp.float64)
        if y0s.ndim != 2:
            raise ValueError(f"initial_states must have shape (batch, n), got {y0s.shape}")
    return np.asarray(y0s, dtype=np.float64)


def _dense_fractions(config: StudyConfig) -> np.ndarray:
    """The dense error grid inside each env step, as fractions of it (its end is the step's boundary)."""
    return np.arange(1, config.dense_points) / config.dense_points


@dataclasses.dataclass
class ScheduleReference:
    """One action schedule of a study and the SciPy reference of its trajectories.

    `inputs` `(T, m)` and `actions` (None for zero input); `states` `(B, T, n)` at the env
    steps' ends and `inside` `(B, T, m - 1, n)` on the dense grid; `floor` bounds the
    reference's own error by its distance from a second solve at ten times the
    tolerance (which is further from the truth than the reference is), `dense_floor` the
    same over the dense grid. `check` holds the discrepancies from an independent
    method, `drifts` the reference's own invariant drifts (zero input).
    """

    schedule: str
    inputs: np.ndarray
    actions: np.ndarray | None
    states: np.ndarray
    inside: np.ndarray
    seconds: float
    floor: float
    dense_floor: float
    check: dict[str, Any]
    drifts: dict[str, float] | None

    def record(self) -> dict[str, Any]:
        """The schedule for the study's JSON record."""
        entry: dict[str, Any] = {
            "inputs": self.inputs.tolist(),
            "actions": None if self.actions is None else self.actions.tolist(),
            "reference_seconds": self.seconds,
            "reference_floor": self.floor,
            "dense_reference_floor": self.dense_floor,
            **self.check,
        }
        if self.drifts is not None:
            entry["reference_drifts"] = self.drifts
        return entry


def _largest_difference(a, a_inside, b, b_inside) -> float:
    return float(max(np.max(np.abs(a - b)), np.max(np.abs(a_inside - b_inside), initial=0.0)))


def _reference(env: AbstractEnv, config: StudyConfig, schedule: str, key, y0s: np.ndarray) -> ScheduleReference:
    inputs, actions = _schedule_inputs(env, config, schedule, key)
    fractions, dt, tolerance = _dense_fractions(config), float(env.dt), config.reference_tolerance

    def solve(method, tol):
        if getattr(env, "contacts", ()):
            # Impacts located as events by SciPy too, restarted at each one.
            return hybrid_reference_trajectories(env, y0s, inputs, dt, fractions, method=method, rtol=tol, atol=tol)
        if getattr(env, "friction", ()):
            # Stick-slip switches located as events by SciPy too, restarted at each one.
            return friction_reference_trajectories(env, y0s, inputs, dt, fractions, method=method, rtol=tol, atol=tol)
        return dense_reference_trajectories(env.physics, y0s, inputs, dt, fractions, method=method, rtol=tol, atol=tol)

    start = time.perf_counter()
    states, inside = solve(config.method, tolerance)
    seconds = time.perf_counter() - start
    looser, looser_inside = solve(config.method, 10 * tolerance)
    check = {}
    if config.check_method is not None:
        other, other_inside = solve(config.check_method, tolerance)
        check = {
            "check_method": config.check_method,
            "check_discrepancy": float(np.max(np.abs(other - states))),
            "dense_check_discrepancy": _largest_difference(other, other_inside, states, inside),
        }
    return ScheduleReference(
        schedule=schedule, inputs=inputs, actions=actions, states=states, inside=inside, seconds=seconds,
        floor=float(np.max(np.abs(looser - states))),
        dense_floor=_largest_difference(looser, looser_inside, states, inside),
        check=check, drifts=invariant_drifts(env.physics, states, y0s) if _measures_drifts(env, schedule) else None,
    )


def _measures_drifts(env: AbstractEnv, schedule: str) -> bool:
    """Whether the rows of `schedule` report invariant drifts: zero input, and no friction add-on,
    whose dry friction takes energy and momentum by physics (its fall is no solver error)."""
    return schedule == "zero" and not getattr(env, "friction", ())


def _row(
    env: AbstractEnv, config: StudyConfig, sweep: SolverSweep, setting: dict[str, Any],
    reference: ScheduleReference, y0s: np.ndarray, timing_floor: float,
) -> dict[str, Any]:
    """One row of the study: `env` (with the setting's integrator) on one schedule.

    Columns as `report.CSV_COLUMNS` documents them.
    """
    inputs = jnp.asarray(reference.inputs)
    (ys, ok, steps, rejected), times = timed_runs(env, jnp.asarray(y0s), inputs, config.repeats)
    solver_ok = bool(np.all(ok))
    deviation = np.max(np.abs(ys - reference.states), axis=-1)  # (B, T)
    dense = None
    # A solver's dense output does not pass an impact or a switch: no dense errors through them.
    if solver_ok and not getattr(env, "contacts", ()) and not getattr(env, "friction", ()):
        dense = dense_errors(env, y0s, ys, inputs, _dense_fractions(config), reference.states, reference.inside)
    accepted = float(np.mean(np.sum(steps, axis=1)))
    attempted = accepted + float(np.mean(np.sum(rejected, axis=1)))
    per_step = evaluations_per_step(env.integrator.solver)
    evaluations = math.nan
    if per_step is not None:
        per_accepted, per_rejected, per_solve = per_step
        evaluations = accepted * per_accepted + (attempted - accepted) * per_rejected + config.horizon * per_solve
    dt = float(env.dt)
    substeps = setting["substeps"]
    row = {
        "scene": config.scene,
        "schedule": reference.schedule,
        "solver": sweep.name,
        "label": sweep.label,
        "order": sweep.description.order or math.nan,
        "controller": _controller_name(env.integrator),
        "dt": dt / substeps if substeps is not None else math.nan,
        "env_dt": dt,
        "substeps": substeps if substeps is not None else "",
        "rtol": setting["rtol"] if setting["rtol"] is not None else math.nan,
        "atol": setting["atol"] if setting["atol"] is not None else math.nan,
        "error": float(np.max(deviation[:, -1])) if solver_ok else math.nan,
        "max_error": float(np.max(deviation)) if solver_ok else math.nan,
        "l2_error": dense["l2_error"] if dense else math.nan,
        "linf_error": dense["linf_error"] if dense else math.nan,
        "seconds": min(times),
        # One timed run has no spread to measure (not a spread of zero).
        "seconds_spread": (float(np.median(times)) - min(times)) / min(times) if len(times) > 1 else math.nan,
        "timing_floor": timing_floor,
        "steps": accepted,
        "attempted_steps": attempted,
        "rejected_steps": attempted - accepted,
        "vector_field_evaluations": evaluations,
        "energy_drift": math.nan,
        "momentum_drift": math.nan,
        "solver_ok": solver_ok,
        "failure": "" if solver_ok else failure_reason(env, ys, ok, reference.inputs),
        "batch": int(y0s.shape[0]),
        "horizon": config.horizon,
        "dtype": str(ys.dtype),
        "reference_method": config.method,
        "reference_tolerance": config.reference_tolerance,
        "reference_floor": reference.floor,
        "dense_points": config.dense_points,
    }
    if _measures_drifts(env, reference.schedule) and solver_ok:
        row.update(invariant_drifts(env.physics, ys, y0s))
    return row


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
        env = make_scene(config.scene, **config.scene_kwargs)
        sweeps = config.sweeps or default_sweeps()
        initial_key, schedule_key = jr.split(jr.key(config.seed))
        y0s = _initial_states(env, config, initial_key)
        references = {
            schedule: _reference(env, config, schedule, key, y0s)
            for schedule, key in zip(config.schedules, jr.split(schedule_key, len(config.schedules)))
        }
        timing_floor = empty_call_seconds(jnp.asarray(y0s))
        settings = [
            (sweep, setting, integrator)
            for sweep in sweeps
            for setting, integrator in sweep.integrators(max_steps=config.max_steps)
        ]
        bar = _progress_bar(len(settings), progress, f"study {config.scene}")
        rows = []
        for sweep, setting, integrator in settings:
            # The env as a user would set it up with this solver.
            study_env = eqx.tree_at(lambda e: e.integrator, env, integrator)
            for reference in references.values():
                rows.append(_row(study_env, config, sweep, setting, reference, y0s, timing_floor))
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
        record = {
            "config": _config_record(config, sweeps),
            "initial_states": y0s.tolist(),
            "dt": float(env.dt),
            "horizon_seconds": config.horizon * float(env.dt),
            "schedules": {name: reference.record() for name, reference in references.items()},
            "reference": {
                "library": "scipy.integrate.solve_ivp",
                "method": config.method,
                "rtol": config.reference_tolerance,
                "atol": config.reference_tolerance,
                "floor_estimate": "max |reference(tol) - reference(10 tol)|, same method",
                "dense_output": "solve_ivp(dense_output=True) of the same solves, at the dense grid's inner points",
            },
            "dense_grid": f"{config.dense_points} points per env step: its end and {config.dense_points - 1} "
                          "equally spaced inside",
            "environment": environment_record(),
        }
    return StudyResult(config=config, rows=rows, record=record)


def _progress_bar(total: int, enabled: bool, description: str):
    if enabled:
        try:
            from tqdm.auto import tqdm
        except ImportError:  # progress bars are optional: pip install 'lerax_like[study]'
            pass
        else:
            return tqdm(total=total, desc=description, leave=False)
    return None


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
