"""Work-precision studies: error against cost for every solver setting, on a real scene.

A study takes a scene, a batch of initial states, action schedules, a horizon in env
steps, and solver sweeps (substeps for fixed-step solvers, paired `rtol`/`atol` for
adaptive ones). For each setting it integrates the batch through the env's own
integrator (`env.integrator.integrate` over `[0, dt]` per env step, the input held, as
`env.transition` does), and measures

- the error against an independent SciPy reference, at the final time and maximal over
  the trajectory (max norm over state components and initial states);
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
from ..integrate import Integrator, make_integrator
from ..spaces import Box, Discrete
from .reference import reference_trajectories
from .scenes import make_scene, reference_method


SCHEDULES = ("zero", "constant", "recorded")


@dataclasses.dataclass(frozen=True)
class SolverSweep:
    """One line of a work-precision diagram: a solver and the settings it is run at.

    - `solver`: a preset name of `make_integrator` (`"euler"`, `"rk4"`, `"tsit5"`, ...).
    - `substeps`: constant-step runs, `substeps` equal steps per env step (step size
      `env.dt / substeps`).
    - `tolerances`: adaptive runs with `PIDController(rtol, atol)`, one per pair.

    Give exactly one of `substeps` and `tolerances`.
    """

    solver: str
    substeps: tuple[int, ...] = ()
    tolerances: tuple[tuple[float, float], ...] = ()

    def __post_init__(self):
        if bool(self.substeps) == bool(self.tolerances):
            raise ValueError(f"SolverSweep({self.solver!r}): give exactly one of substeps and tolerances")
        if any(int(k) != k or k < 1 for k in self.substeps):
            raise ValueError(f"SolverSweep({self.solver!r}): substeps must be positive integers, got {self.substeps}")
        if any(not (r > 0 and a > 0) for r, a in self.tolerances):
            raise ValueError(f"SolverSweep({self.solver!r}): rtol and atol must be > 0, got {self.tolerances}")

    @property
    def adaptive(self) -> bool:
        return bool(self.tolerances)

    @property
    def label(self) -> str:
        return f"{self.solver} (PID)" if self.adaptive else self.solver

    def integrators(self) -> list[tuple[dict[str, Any], Integrator]]:
        """`(setting, integrator)` for every setting of the sweep."""
        if self.adaptive:
            # Tolerances as arrays, not Python floats: they are then traced leaves, and
            # one compilation serves the whole tolerance sweep.
            return [
                (
                    {"rtol": rtol, "atol": atol, "substeps": None},
                    make_integrator(
                        self.solver,
                        diffrax.PIDController(rtol=jnp.asarray(rtol), atol=jnp.asarray(atol)),
                    ),
                )
                for rtol, atol in self.tolerances
            ]
        return [
            (
                {"rtol": None, "atol": None, "substeps": k},
                make_integrator(self.solver, diffrax.ConstantStepSize(), substeps=k),
            )
            for k in self.substeps
        ]


def _powers_of_two(n: int) -> tuple[int, ...]:
    return tuple(2**i for i in range(n))


def _tolerance_pairs(exponents: Sequence[int]) -> tuple[tuple[float, float], ...]:
    # DiffEqDevTools' convention: atol three orders below rtol.
    return tuple((10.0**-e, 10.0 ** -(e + 3)) for e in exponents)


def default_sweeps(*, quick: bool = False) -> tuple[SolverSweep, ...]:
    """The solvers and settings of `lerax-like study`: every order from 1 to 8."""
    if quick:
        # Each substep count is a separate compilation (substeps shape the solve), so
        # the quick study keeps few: enough for Euler's and RK4's orders below 1e-2.
        return (
            SolverSweep("euler", substeps=(16, 64, 256)),
            SolverSweep("rk4", substeps=(1, 2, 4)),
            SolverSweep("tsit5", tolerances=_tolerance_pairs([4, 7, 9, 11])),
        )
    return (
        SolverSweep("euler", substeps=_powers_of_two(11)),
        SolverSweep("heun", substeps=_powers_of_two(8)),
        SolverSweep("midpoint", substeps=_powers_of_two(8)),
        SolverSweep("rk4", substeps=_powers_of_two(6)),
        SolverSweep("tsit5", substeps=_powers_of_two(4)),
        SolverSweep("tsit5", tolerances=_tolerance_pairs(range(4, 13))),
        SolverSweep("dopri5", tolerances=_tolerance_pairs(range(4, 13))),
        SolverSweep("dopri8", tolerances=_tolerance_pairs(range(4, 13))),
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

    def __post_init__(self):
        unknown = set(self.schedules) - set(SCHEDULES)
        if unknown or not self.schedules:
            raise ValueError(f"schedules must be a non-empty subset of {SCHEDULES}, got {self.schedules}")
        for name in ("horizon", "batch", "repeats"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not self.reference_tolerance > 0:
            raise ValueError(f"reference_tolerance must be > 0, got {self.reference_tolerance}")

    @classmethod
    def default(cls, scene: str = "CartPole", *, quick: bool = False, **overrides) -> "StudyConfig":
        """The study `lerax-like study SCENE [--quick]` runs."""
        settings: dict[str, Any] = dict(scene=scene, sweeps=default_sweeps(quick=quick))
        if quick:
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
    """`(per accepted step, per rejected step, once per solve)` vector-field evaluations.

    Read from the Butcher tableau of an explicit solver: `s` stages per step, or, for a
    first-same-as-last method (Tsit5, Dopri5), `s - 1` per accepted step (its first
    stage is the last of the step before) plus one at the start of each solve. A
    rejected step costs all `s` (diffrax 0.7 does not reuse the first stage after a
    rejection: counted in tests/test_study.py). `None` for implicit solvers, whose
    count depends on the root finder.
    """
    if isinstance(solver, diffrax.Euler):
        return 1, 1, 0
    tableau = getattr(solver, "tableau", None)
    if not isinstance(solver, diffrax.AbstractERK) or not isinstance(tableau, diffrax.ButcherTableau):
        return None
    stages = len(tableau.c) + 1
    return (stages - 1, stages, 1) if tableau.fsal else (stages, stages, 0)


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

    # One reference per schedule, with its floor.
    schedules: dict[str, dict[str, Any]] = {}
    for schedule, key in zip(config.schedules, jr.split(schedule_key, len(config.schedules))):
        inputs, actions = _schedule_inputs(env, config, schedule, key)
        start = time.perf_counter()
        reference = reference_trajectories(
            env.physics, y0s_np, inputs, dt, method=method, rtol=tolerance, atol=tolerance
        )
        reference_seconds = time.perf_counter() - start
        looser = reference_trajectories(
            env.physics, y0s_np, inputs, dt, method=method, rtol=10 * tolerance, atol=10 * tolerance
        )
        entry = {
            "inputs": inputs,
            "actions": actions,
            "reference": reference,
            "reference_seconds": reference_seconds,
            # The reference at ten times its tolerance differs from the truth by more
            # than the reference does: a conservative bound on the reference's error.
            "reference_floor": float(np.max(np.abs(looser - reference))),
        }
        if config.check_method is not None:
            check = reference_trajectories(
                env.physics, y0s_np, inputs, dt, method=config.check_method, rtol=tolerance, atol=tolerance
            )
            entry["check_discrepancy"] = float(np.max(np.abs(check - reference)))
        if schedule == "zero":
            entry["reference_drifts"] = _invariant_drifts(env.physics, reference, y0s_np)
        schedules[schedule] = entry

    settings = [(sweep, setting, integrator) for sweep in sweeps for setting, integrator in sweep.integrators()]
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
                "solver": sweep.solver,
                "label": sweep.label,
                "controller": _controller_name(integrator),
                "dt": dt / setting["substeps"] if setting["substeps"] is not None else math.nan,
                "env_dt": dt,
                "substeps": setting["substeps"] if setting["substeps"] is not None else "",
                "rtol": setting["rtol"] if setting["rtol"] is not None else math.nan,
                "atol": setting["atol"] if setting["atol"] is not None else math.nan,
                "error": float(np.max(deviation[:, -1])) if solver_ok else math.nan,
                "max_error": float(np.max(deviation)) if solver_ok else math.nan,
                "seconds": min(times),
                "steps": accepted_per_trajectory,
                "attempted_steps": attempted_per_trajectory,
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
                **({"check_method": config.check_method, "check_discrepancy": entry["check_discrepancy"]}
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
        },
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
        "sweeps": [dataclasses.asdict(sweep) for sweep in sweeps],
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
