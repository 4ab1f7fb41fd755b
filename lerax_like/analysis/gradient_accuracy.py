"""Gradient accuracy: how far the gradient of the discretised env is from the continuous system's.

An env's gradient (with the default `RecursiveCheckpointAdjoint`, or `ForwardMode`) is
the exact derivative of the *discrete* solution. That is what an optimiser of the env
sees, but when the env stands for a physical system, the quantity of interest is the
derivative of the continuous system: they differ by an error that shrinks with the
solver's step like the solver's own error, and it can flip a gradient's sign.
`gradient_work_precision` measures this error against a tight reference, beside the run
time of the gradient: the work-precision idea applied to gradients. `run_gradient_study`
does it for a scene by name (`lerax-like gradients SCENE`);
`lerax_like.gradients.sensitivity_signs` finds where a solver's sensitivity has the wrong
sign along a trajectory.
"""

import dataclasses
import math
import os
import time
from collections.abc import Callable, Sequence
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax.flatten_util import ravel_pytree

from .._fields import check_count
from .._types import Array, BoolScalar, Float, Scalar, State
from ..env import AbstractEnv, EnvState, rollout
from ..gradients import reference_integrator, selection_spec, with_adjoint, with_integrator
from ..integrate import Integrator, describe_solver
from .convergence import convergence_orders
from .figures import plot_gradient_work_precision
from .modes_reference import modes_reference_gradient, uses_modes_reference
from .parameters import check_parameter_names, parameter_names, parameter_where
from .recording import PLOT_HINT, environment_record, matplotlib_available, write_record
from .recording import write_csv as write_rows
from .scenes import SCENES, make
from .sweeps import SolverSweep, tolerance_pairs


GRADIENT_CSV_COLUMNS = (
    "scene", "solver", "label", "controller", "dt", "env_dt", "substeps", "rtol", "atol", "error", "seconds",
    "solver_ok", "mode", "horizon", "reference_rtol", "reference_floor",
)
"""One row per solver setting of a gradient study. `error` is the relative 2-norm error of
the gradient against the reference; `seconds` the median time of one gradient; `dt` the
solver's step (fixed-step rows); `reference_floor` the reference's own relative error
estimate. The gradients themselves are in the JSON."""


Loss = Callable[[AbstractEnv], tuple[Scalar, BoolScalar]]
"""A scalar loss of an env, and whether every solve behind it succeeded."""


def mean_squared_state(ys: Float[Array, "T n"]) -> Scalar:
    """Mean over the rollout of `|y_t|^2`: smooth in every state component."""
    return jnp.mean(jnp.sum(ys**2, axis=-1))


def trajectory_loss(
    y0: State, actions: Array, cost: Callable[[Float[Array, "T n"]], Scalar] = mean_squared_state
) -> Loss:
    """The loss `cost(ys)` of the rollout of `actions` from `y0`, with the solves' success.

    The rollout has no termination and no reset (`lerax_like.rollout`), so the loss is
    as smooth as the dynamics and `cost` are.
    """

    def loss(env: AbstractEnv) -> tuple[Scalar, BoolScalar]:
        state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
        ys, infos = rollout(env, state, actions, key=jr.key(0))
        return cost(ys), jnp.all(infos["solver_ok"])

    return loss


def _timed(fn, *args, repeats: int = 5) -> float:
    jax.block_until_ready(fn(*args))  # compile first
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def _gradient_function(loss: Loss, mode: Literal["reverse", "forward"]):
    """`(params, static) -> (gradient, solver_ok)`, jitted once for every integrator.

    The integrator lies in `static`: its arrays (an adaptive controller's tolerances) are
    traced, so that a tolerance sweep shares one compilation.
    """
    differentiate = jax.grad if mode == "reverse" else jax.jacfwd

    @eqx.filter_jit
    def gradient(params, static):
        return differentiate(lambda p: loss(eqx.combine(p, static)), has_aux=True)(params)

    return gradient


def _integrator_setting(env: AbstractEnv, integrator: Integrator) -> dict[str, Any]:
    controller = integrator.stepsize_controller
    constant = not integrator.adaptive
    return {
        "controller": type(controller).__name__,
        "substeps": integrator.substeps if constant else "",
        "dt": float(env.dt) / integrator.substeps if constant else math.nan,
        "env_dt": float(env.dt),
        "rtol": float(getattr(controller, "rtol", math.nan)),
        "atol": float(getattr(controller, "atol", math.nan)),
    }


def gradient_work_precision(
    env: AbstractEnv,
    loss: Loss,
    where: Callable[[AbstractEnv], Any],
    integrators: Sequence[tuple[str, Integrator]],
    *,
    mode: Literal["reverse", "forward"] = "reverse",
    reference_rtol: float = 1e-12,
    repeats: int = 5,
    independent: dict[str, Any] | None = None,
) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Error and run time of the gradient of `loss` with respect to `where(env)`, per integrator.

    - `loss(env)` returns the loss and whether all its solves succeeded (`trajectory_loss`).
    - `mode`: `"reverse"` times `jax.grad` with each integrator's own adjoint (the default
      `RecursiveCheckpointAdjoint`, or one under study such as `BacksolveAdjoint`);
      `"forward"` times `jax.jacfwd` with `ForwardMode`. Both checkpoint and forward give
      the exact derivative of the discrete solution; forward is cheaper for a handful of
      parameters.

    The error is `|g - g_ref| / |g_ref|` (2-norm over all selected leaves), `NaN` where a
    solve failed. `g_ref` is computed with `reference_integrator(reference_rtol)` by
    forward mode (exact for the discrete reference solution, and its compilation is the
    cheaper); its floor estimates its own error. Given an `independent` reference instead
    (`gradient`, flattened as the selection, and its `floor`: a hybrid scene takes
    `modes_reference_gradient`'s), the errors are against it, and Dopri8's own error
    against it is recorded as `dopri8_discrepancy`.

    Returns the rows, one per integrator (`label`, `controller`, `substeps`, `dt` (the
    solver's step, fixed-step rows), `env_dt`, `rtol`, `atol`, `error`, `seconds` (median
    of `repeats` after a compiling run), `solver_ok`, `gradient`), and the reference
    (`gradient`, `rtol`, `floor`).
    """
    if mode not in ("reverse", "forward"):
        raise ValueError(f"mode must be 'reverse' or 'forward', got {mode!r}")

    def parts(integrator, adjoint):
        env_i = with_integrator(env, integrator)
        if adjoint is not None:
            env_i = with_adjoint(env_i, adjoint)
        return eqx.partition(env_i, selection_spec(env_i, where))

    reference_gradient = _gradient_function(loss, "forward")
    g_ref, ok = reference_gradient(*parts(reference_integrator(reference_rtol), "forward"))
    # The floor: against a second reference at ten times the tolerance and at most a
    # quarter of the env step per step. Where the step bound binds (Dopri8 at tight
    # tolerances still takes one step per short env step) the second is the finer and
    # the difference is the reference's own error; where it does not, the second is
    # the coarser, and the difference overestimates it.
    check = reference_integrator(10 * reference_rtol, dtmax=float(env.dt) / 4)
    g_check, ok_check = reference_gradient(*parts(check, "forward"))
    if not (bool(ok) and bool(ok_check)):
        raise RuntimeError(f"the reference solve (Dopri8, rtol {reference_rtol:g}) failed: raise its budget or loosen it")
    g_ref, g_check = ravel_pytree(g_ref)[0], ravel_pytree(g_check)[0]
    scale = jnp.linalg.norm(g_ref)
    reference = {
        "gradient": np.asarray(g_ref).tolist(),
        "rtol": reference_rtol,
        "floor": float(jnp.linalg.norm(g_check - g_ref) / scale),
    }
    if independent is not None:
        dopri8 = g_ref
        g_ref = jnp.asarray(independent["gradient"], dopri8.dtype)
        scale = jnp.linalg.norm(g_ref)
        reference = {**independent, "dopri8_discrepancy": float(jnp.linalg.norm(dopri8 - g_ref) / scale)}

    gradient = reference_gradient if mode == "forward" else _gradient_function(loss, mode)
    rows = []
    for label, integrator in integrators:
        params, static = parts(integrator, "forward" if mode == "forward" else None)
        g, ok = gradient(params, static)
        g = ravel_pytree(g)[0]
        rows.append(
            {
                "label": label,
                **_integrator_setting(env, integrator),
                "error": float(jnp.linalg.norm(g - g_ref) / scale) if bool(ok) else math.nan,
                "seconds": _timed(gradient, params, static, repeats=repeats),
                "solver_ok": bool(ok),
                "gradient": np.asarray(g).tolist(),
            }
        )
    return rows, reference


def _scene_projects(name: str) -> bool:
    """Whether the scene clips or wraps its state after each step (a `project` override)."""
    return SCENES[name].projects_state()


def gradient_scenes() -> tuple[str, ...]:
    """Scenes whose rollout loss is smooth, which `run_gradient_study` takes.

    Left out are scenes that clip or wrap their state after every step (Gymnasium's speed
    limits and walls, angle wrapping): where a clip is active the loss has a kink, and the
    gradient there is no derivative of the continuous system to converge to.
    """
    return tuple(name for name in SCENES if not _scene_projects(name))


def default_gradient_sweeps(*, quick: bool = False) -> tuple[SolverSweep, ...]:
    """The solvers and settings of `lerax-like gradients`."""
    if quick:
        # Each substep count is a separate compilation (substeps shape the solve), the
        # tolerances of one solver share one: two points per fixed-step order.
        return (
            SolverSweep("euler", substeps=(1, 4)),
            SolverSweep("rk4", substeps=(1, 4)),
            SolverSweep("tsit5", tolerances=tolerance_pairs([4, 8])),
        )
    powers = (1, 2, 4, 8, 16, 32)
    return (
        SolverSweep("euler", substeps=powers),
        SolverSweep("midpoint", substeps=powers),
        SolverSweep("rk4", substeps=powers),
        SolverSweep("tsit5", tolerances=tolerance_pairs([3, 5, 7, 9])),
        SolverSweep("dopri5", tolerances=tolerance_pairs([3, 5, 7, 9])),
        SolverSweep("kvaerno5", tolerances=tolerance_pairs([3, 5, 7, 9])),
    )


def gradient_sweeps_for(solvers: Sequence[Any], *, quick: bool = False) -> tuple[SolverSweep, ...]:
    """The sweeps of `lerax-like gradients --solver NAME ...`.

    A solver without an error estimate over substeps, one with an estimate over substeps
    and tolerances (as `lerax-like study --solver`).
    """
    substeps = (1, 4) if quick else (1, 2, 4, 8, 16, 32)
    exponents = [4, 8] if quick else [3, 5, 7, 9]
    sweeps = []
    for solver in solvers:
        name = describe_solver(solver).name
        sweeps.append(SolverSweep(solver, substeps=substeps, name=name))
        if describe_solver(solver).error_estimate:
            sweeps.append(SolverSweep(solver, tolerances=tolerance_pairs(exponents), name=name))
    return tuple(sweeps)


@dataclasses.dataclass(frozen=True)
class GradientStudyConfig:
    """Everything a gradient study depends on; the JSON record holds it.

    - `scene`, `scene_kwargs`: the env, by its name in `gradient_scenes()`, and its keywords.
    - `sweeps`: the solver settings (`default_gradient_sweeps()` if empty).
    - `horizon`: env steps of the rollout; `seed`: draws the initial state from
      `env.initial` and the actions from the action space, unless `initial_state`,
      `actions` are given.
    - `parameters`: names of fields of `env.dynamics` (or of a friction add-on, a floor) to
      differentiate with respect to (`None`: all of them, the physical parameters); the
      record's `parameter_names` lists them in the env's leaf order, the gradient's.
    - `cost`: the loss of the trajectory `ys` (default `mean_squared_state`).
    - `mode`, `repeats`, `reference_rtol`: as in `gradient_work_precision`. Forward mode
      by default: with a handful of parameters it is the cheaper exact mode.
    - `fit_ceiling`: orders are fitted to gradient errors below it.
    """

    scene: str = "CartPole"
    scene_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    sweeps: tuple[SolverSweep, ...] = ()
    horizon: int = 100
    seed: int = 0
    initial_state: Any = None
    actions: Any = None
    parameters: tuple[str, ...] | None = None
    cost: Callable[[Float[Array, "T n"]], Scalar] = mean_squared_state
    mode: Literal["reverse", "forward"] = "forward"
    repeats: int = 5
    reference_rtol: float = 1e-12
    fit_ceiling: float = 0.2

    def __post_init__(self):
        if self.scene not in SCENES:
            raise ValueError(f"unknown scene {self.scene!r}; the gradient study takes: {', '.join(gradient_scenes())}")
        if _scene_projects(self.scene):
            raise ValueError(
                f"{self.scene} clips or wraps its state after every step (its `project`), so the "
                "gradient of a rollout loss has kinks and no continuous-time limit to measure against; "
                f"the gradient study takes: {', '.join(gradient_scenes())}"
            )
        if self.mode not in ("reverse", "forward"):
            raise ValueError(f"mode must be 'reverse' or 'forward', got {self.mode!r}")
        check_count(self.horizon, "horizon")
        check_count(self.repeats, "repeats")
        if not self.reference_rtol > 0:
            raise ValueError(f"reference_rtol must be > 0, got {self.reference_rtol}")

    @classmethod
    def default(cls, scene: str = "CartPole", *, quick: bool = False, **overrides) -> "GradientStudyConfig":
        """The study `lerax-like gradients SCENE [--quick]` runs."""
        settings: dict[str, Any] = dict(scene=scene, sweeps=default_gradient_sweeps(quick=quick))
        if quick:
            settings.update(repeats=3)
            if scene in SCENES and uses_modes_reference(make(scene, **overrides.get("scene_kwargs", {}))):
                # The reference through the modes costs six SciPy rollouts per parameter.
                settings.update(horizon=20)
        settings.update(overrides)
        return cls(**settings)


def _describe(function: Callable) -> str:
    """A function's name and the first line of its docstring, for the record."""
    doc = (function.__doc__ or "").strip()
    return f"{function.__name__}: {doc.splitlines()[0]}" if doc else function.__name__


@dataclasses.dataclass
class GradientStudyResult:
    """The rows of a gradient study (one per solver setting; see `gradient_work_precision`),
    its `record` (configuration, rollout, reference, environment) and its `config`.

    `write` writes its files; `convergence_orders` fits the order of the gradient error per
    fixed-step solver.
    """

    config: GradientStudyConfig
    rows: list[dict[str, Any]]
    record: dict[str, Any]

    def convergence_orders(self) -> list[dict[str, Any]]:
        """Fitted slopes of log gradient error on log step size, per fixed-step solver."""
        return convergence_orders(self.rows, ceiling=self.config.fit_ceiling)

    def write(self, out: "str | os.PathLike", **options) -> dict[str, str]:
        """`write_gradient_study(self, out, **options)`: the CSV, the JSON record and the figure."""
        return write_gradient_study(self, out, **options)


def run_gradient_study(config: GradientStudyConfig) -> GradientStudyResult:
    """Run `config` (in float64) and return its rows, one per solver setting.

    See `gradient_work_precision` for what a row holds; `result.convergence_orders()`
    gives the order of the gradient error per fixed-step solver.
    """
    with jax.enable_x64(True):
        return _run_gradient_study(config)


def _run_gradient_study(config: GradientStudyConfig) -> GradientStudyResult:
    env = make(config.scene, **config.scene_kwargs)
    if config.parameters is not None:
        check_parameter_names(env, config.parameters, config.scene)
    initial_key, action_key = jr.split(jr.key(config.seed))
    if config.initial_state is None:
        y0 = env.initial(key=initial_key).y
    else:
        y0 = jnp.asarray(config.initial_state, dtype=jnp.float64)
    if config.actions is None:
        actions = jax.vmap(lambda k: env.action_space.sample(key=k))(jr.split(action_key, config.horizon))
    else:
        actions = jnp.asarray(config.actions)
        if actions.shape[0] != config.horizon:
            raise ValueError(f"actions has {actions.shape[0]} steps, horizon is {config.horizon}")
    sweeps = config.sweeps or default_gradient_sweeps()
    where = parameter_where(env, config.parameters)
    settings = [(sweep, integrator) for sweep in sweeps for _, integrator in sweep.integrators()]
    independent, solver = None, "dopri8 (diffrax), PIDController, atol = rtol / 100, forward mode"
    floor_estimate = "|g_check - g| / |g|, g_check at 10 rtol and dtmax = dt / 4"
    if uses_modes_reference(env):
        # Through stick-slip switches and impacts with friction: central differences of SciPy's
        # event-located reference, which owes nothing to diffrax's root find or to automatic
        # differentiation.
        inputs = jax.vmap(env.physical_input)(actions)
        independent = modes_reference_gradient(env, where, y0, inputs, config.cost)
        solver = ("central differences (fourth order) of scipy.integrate.solve_ivp DOP853 restarted at every "
                  "located event of the scene's modes (lerax_like.analysis.modes_reference)")
        floor_estimate = "|g(2h) - g(h)| / |g(h)|, the stencil at twice the step"
    rows, reference = gradient_work_precision(
        env,
        trajectory_loss(y0, actions, config.cost),
        where,
        [(sweep.label, integrator) for sweep, integrator in settings],
        mode=config.mode,
        reference_rtol=config.reference_rtol,
        repeats=config.repeats,
        independent=independent,
    )
    for (sweep, _), row in zip(settings, rows):
        row.update(
            scene=config.scene, solver=sweep.name, mode=config.mode, horizon=config.horizon,
            reference_rtol=reference["rtol"], reference_floor=reference["floor"],
        )
    record = {
        "config": {
            "scene": config.scene,
            "scene_kwargs": config.scene_kwargs,
            "sweeps": [sweep.record() for sweep in sweeps],
            "horizon": config.horizon,
            "seed": config.seed,
            "parameters": config.parameters,
            "cost": _describe(config.cost),
            "mode": config.mode,
            "repeats": config.repeats,
            "reference_rtol": config.reference_rtol,
            "fit_ceiling": config.fit_ceiling,
            "dtype": "float64",
        },
        "dt": float(env.dt),
        "initial_state": np.asarray(y0).tolist(),
        "actions": np.asarray(actions).tolist(),
        "parameter_names": parameter_names(env, where),
        "reference": {"solver": solver, **reference, "floor_estimate": floor_estimate},
        "environment": environment_record(),
    }
    return GradientStudyResult(config=config, rows=rows, record=record)




def write_gradient_study(
    result: "GradientStudyResult", out: str | os.PathLike, *, plot: bool = True, stem: str | None = None,
    signs: dict[str, Any] | None = None, **extra,
) -> dict[str, str]:
    """Write a gradient study's `<stem>.csv`, `<stem>.json` and (if `plot`) `<stem>.png` into `out`,
    all through `recording`, the one writer.

    `result` is what `run_gradient_study` returns; `stem` defaults to `<scene>_gradients`;
    `signs` (from `sensitivity_signs`) goes into the JSON and the plot, `extra` into the JSON.
    """
    os.makedirs(out, exist_ok=True)
    stem = os.path.join(out, stem or f"{result.config.scene}_gradients")
    paths = {"csv": stem + ".csv", "json": stem + ".json"}
    write_rows(result.rows, paths["csv"], columns=GRADIENT_CSV_COLUMNS)
    record = {**result.record, "rows": result.rows, "convergence_orders": result.convergence_orders()}
    if signs is not None:
        record["wrong_sign"] = signs
    if plot and matplotlib_available():
        paths["png"] = stem + ".png"
        plot_gradient_work_precision(result.rows, paths["png"], signs=signs)
    elif plot:
        record["figure"] = {"skipped": f"matplotlib is not installed: {PLOT_HINT}"}
    write_record({**record, **extra}, paths["json"])
    return paths


# The sensitivities are gradient tools, in `lerax_like.gradients` now.
