"""The work-precision study: its configuration, its run, its result and the one way its files are written."""


import dataclasses
import math
import os
from collections.abc import Iterable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ...env import AbstractEnv
from ...integrate import Integrator
from ..convergence import convergence_orders
from ..figures import plot_work_precision
from ..measurements import (
    dense_errors,
    empty_call_seconds,
    evaluations_per_step,
    failure_reason,
    invariant_drifts,
    timed_runs,
)
from ..recording import PLOT_HINT, environment_record, matplotlib_available, read_csv_rows, write_record
from ..recording import write_csv as write_rows
from ..scenes import SCENES, make, reference_method
from ..sweeps import SolverSweep, default_sweeps
from ..verdict import cheapest_at, failures, order_disagreements
from ._schedules import (
    SCHEDULES,
    ScheduleReference,
    dense_fractions,
    initial_states,
    measures_drifts,
    schedule_inputs,
    schedule_reference,
)


CSV_COLUMNS = (
    "scene", "schedule", "solver", "label", "order", "controller", "dt", "env_dt", "substeps", "rtol", "atol",
    "error", "max_error", "l2_error", "linf_error", "seconds", "seconds_spread", "timing_floor",
    "steps", "attempted_steps", "rejected_steps", "vector_field_evaluations",
    "energy_drift", "momentum_drift", "solver_ok", "failure", "batch", "horizon", "dtype",
    "reference_method", "reference_tolerance", "reference_floor", "dense_points",
)
"""One row per schedule and solver setting. `solver` is the solver's name (a preset's, or
its class name) and `order` the method's order (empty if unknown). `error` is the
max-norm error at the final time, `max_error` over the env-step ends; `l2_error` (root
mean square) and `linf_error` (maximum) are over a dense grid of `dense_points` per env
step including its end, from the solver's own dense output against SciPy's (as
DiffEqDevTools' `L2` and `Linf`); all maximal over the batch. `seconds` is the minimum
over repeats of the whole batch's run, `seconds_spread` (median - min) / min over the
repeats (empty for a single repeat), `timing_floor` the time of an empty compiled call; `steps` accepted,
`rejected_steps` rejected solver steps and `vector_field_evaluations` per trajectory;
`dt` the solver's step (fixed-step rows); `failure`, where `solver_ok` is False, why the
setting failed and where (`measurements.failure_reason`: step budget exhausted, step size
collapsed, root finder failed, non-finite state)."""


VERDICT_TARGETS = (1e-3, 1e-6, 1e-9)
"""The error levels at which a study names its cheapest setting."""

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


    def record(self, sweeps: Sequence[SolverSweep]) -> dict[str, Any]:
        """The configuration for the JSON record, `sweeps` as run (the defaults where `sweeps` is empty)."""

        def plain(value):
            if isinstance(value, (np.ndarray, jax.Array)):
                return np.asarray(value).tolist()
            return value

        return {
            "scene": self.scene,
            "scene_kwargs": {k: plain(v) for k, v in self.scene_kwargs.items()},
            "sweeps": [sweep.record() for sweep in sweeps],
            "schedules": list(self.schedules),
            "horizon": self.horizon,
            "batch": self.batch,
            "repeats": self.repeats,
            "seed": self.seed,
            "initial_states": plain(self.initial_states),
            "actions": plain(self.actions),
            "constant_action": plain(self.constant_action),
            "reference_method": self.method,
            "reference_tolerance": self.reference_tolerance,
            "check_method": self.check_method,
            "fit_ceiling": self.fit_ceiling,
            "dense_points": self.dense_points,
            "max_steps": self.max_steps,
            "dtype": "float64",
        }


def _controller_name(integrator: Integrator) -> str:
    return type(integrator.stepsize_controller).__name__


def _row(
    env: AbstractEnv, sweep: SolverSweep, setting: dict[str, Any], reference: ScheduleReference,
    y0s: np.ndarray, timing_floor: float, *, scene: str, horizon: int, repeats: int, dense_points: int,
    reference_method: str, reference_tolerance: float,
) -> dict[str, Any]:
    """One row of the study: `env` (with the setting's integrator) on one schedule.

    Columns as `CSV_COLUMNS` documents them.
    """
    inputs = jnp.asarray(reference.inputs)
    (ys, ok, steps, rejected), times = timed_runs(env, jnp.asarray(y0s), inputs, repeats)
    solver_ok = bool(np.all(ok))
    deviation = np.max(np.abs(ys - reference.states), axis=-1)  # (B, T)
    dense = None
    # A solver's dense output does not pass an impact or a switch: no dense errors through them.
    if solver_ok and env.modes() is None:
        dense = dense_errors(env, y0s, ys, inputs, dense_fractions(dense_points), reference.states, reference.inside)
    accepted = float(np.mean(np.sum(steps, axis=1)))
    attempted = accepted + float(np.mean(np.sum(rejected, axis=1)))
    per_step = evaluations_per_step(env.integrator.solver)
    evaluations = math.nan
    if per_step is not None:
        per_accepted, per_rejected, per_solve = per_step
        evaluations = accepted * per_accepted + (attempted - accepted) * per_rejected + horizon * per_solve
    dt = float(env.dt)
    substeps = setting["substeps"]
    row = {
        "scene": scene,
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
        "horizon": horizon,
        "dtype": str(ys.dtype),
        "reference_method": reference_method,
        "reference_tolerance": reference_tolerance,
        "reference_floor": reference.floor,
        "dense_points": dense_points,
    }
    if measures_drifts(env, reference.schedule) and solver_ok:
        row.update(invariant_drifts(env.physics, ys, y0s))
    return row


@dataclasses.dataclass
class StudyResult:
    """The rows of a work-precision study (one per schedule and setting, columns as
    `CSV_COLUMNS`), its `record` (configuration, references, environment) and its `config`.

    `write` writes its files; `convergence_orders` fits the fixed-step solvers' orders.
    """

    config: Any
    rows: list[dict[str, Any]]
    record: dict[str, Any]

    def convergence_orders(self) -> list[dict[str, Any]]:
        """Fitted slopes of log error on log step size, per schedule and fixed-step solver."""
        return convergence_orders(self.rows, ceiling=self.config.fit_ceiling)

    def write(self, out: "str | os.PathLike", **options) -> dict[str, str]:
        """`write_study(self, out, **options)`: the CSV, the JSON record and the figure."""
        return write_study(self, out, **options)


def run_study(config: StudyConfig, *, progress: bool = True) -> StudyResult:
    """Run `config` (in float64) and return its rows; see `lerax_like.analysis.study`."""
    with jax.enable_x64(True):
        env = make(config.scene, **config.scene_kwargs)
        sweeps = config.sweeps or default_sweeps()
        initial_key, schedule_key = jr.split(jr.key(config.seed))
        y0s = initial_states(env, initial_key, config.batch, config.initial_states)
        fractions = dense_fractions(config.dense_points)
        references = {}
        for schedule, key in zip(config.schedules, jr.split(schedule_key, len(config.schedules))):
            inputs, actions = schedule_inputs(
                env, schedule, key, config.horizon, actions=config.actions, constant_action=config.constant_action
            )
            references[schedule] = schedule_reference(
                env, schedule, inputs, actions, y0s, fractions, method=config.method,
                tolerance=config.reference_tolerance, check_method=config.check_method,
            )
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
                rows.append(_row(
                    study_env, sweep, setting, reference, y0s, timing_floor, scene=config.scene,
                    horizon=config.horizon, repeats=config.repeats, dense_points=config.dense_points,
                    reference_method=config.method, reference_tolerance=config.reference_tolerance,
                ))
            if bar is not None:
                bar.update(1)
        if bar is not None:
            bar.close()
        record = {
            "config": config.record(sweeps),
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
            # disable=None: no bar where stderr is no terminal (a log file, a pipe), which it would fill.
            return tqdm(total=total, desc=description, leave=False, disable=None)
    return None


def write_csv(
    rows: Iterable[dict[str, Any]], path: "str | os.PathLike", *, columns: Sequence[str] = CSV_COLUMNS
) -> None:
    """Write a study's rows as CSV (`recording.write_csv` with the study's columns)."""
    write_rows(rows, path, columns=columns)


def read_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a study CSV, numbers parsed (empty cells as NaN)."""
    numeric = {
        "dt", "env_dt", "rtol", "atol", "order", "error", "max_error", "l2_error", "linf_error", "seconds",
        "seconds_spread", "timing_floor", "steps", "attempted_steps", "rejected_steps",
        "vector_field_evaluations", "energy_drift", "momentum_drift", "reference_tolerance", "reference_floor",
    }
    rows = []
    for raw in read_csv_rows(path):
        row: dict[str, Any] = dict(raw)
        for key in numeric & raw.keys():
            row[key] = float(raw[key]) if raw[key] != "" else math.nan
        for key in ("substeps", "batch", "horizon", "dense_points"):
            if raw.get(key):
                row[key] = int(raw[key])
        row["solver_ok"] = raw.get("solver_ok") == "True"
        rows.append(row)
    return rows


def write_json(result: StudyResult, path: "str | os.PathLike", **extra) -> None:
    """The study's JSON record: its configuration, references, orders and verdicts.

    `cheapest` is the verdict (`cheapest_at` by its default measure), one per level;
    `cheapest_by_evaluations` the same by evaluations alone and `cheapest_by_seconds` by
    resolved timings alone (None where no resolved timing reached the level).
    """
    record = dict(result.record)
    record["convergence_orders"] = result.convergence_orders()
    record["cheapest"] = {f"{t:.0e}": cheapest_at(result.rows, t) for t in VERDICT_TARGETS}
    record["cheapest_by_seconds"] = {f"{t:.0e}": cheapest_at(result.rows, t, cost="seconds") for t in VERDICT_TARGETS}
    record["cheapest_by_evaluations"] = {
        f"{t:.0e}": cheapest_at(result.rows, t, cost="vector_field_evaluations") for t in VERDICT_TARGETS
    }
    record["order_disagreements"] = order_disagreements(record["convergence_orders"])
    record["failures"] = failures(result.rows)
    record.update(extra)
    write_record(record, path)


def write_study(
    result: StudyResult, out: str | os.PathLike, *, plot: bool = True, stem: str | None = None,
    title: str | None = None, **extra,
) -> dict[str, str]:
    """Write `<stem>.csv`, `<stem>.json` and (if `plot`) `<stem>.png` into `out` (stem: the scene),
    all through `recording`, the one writer; `extra` goes into the JSON.

    Without matplotlib the plot is skipped, not an error: `paths` then has no `"png"`
    and the JSON says `"figure": {"skipped": ...}`. The JSON records the legend's labels
    and the failed settings the figure marks (`"figure": {"failed": ...}`).
    """
    os.makedirs(out, exist_ok=True)
    stem = os.path.join(out, stem or result.config.scene)
    paths = {"csv": stem + ".csv", "json": stem + ".json"}
    write_csv(result.rows, paths["csv"])
    figure_record: dict[str, Any] = {"skipped": "not asked for"}
    if plot:
        if matplotlib_available():
            figure = plot_work_precision(result.rows, stem + ".png", title=title,
                                         fit_ceiling=result.config.fit_ceiling)
            paths["png"] = stem + ".png"
            figure_record = {"path": os.path.basename(paths["png"]), "legend": getattr(figure, "legend_labels"),
                             "failed": getattr(figure, "failed_settings")}
        else:
            figure_record = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    write_json(result, paths["json"], figure=figure_record, **extra)
    return paths
