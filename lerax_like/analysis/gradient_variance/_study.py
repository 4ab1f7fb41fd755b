"""The gradient-variance study: its configuration, its run, its result and the one way its files are written."""


import dataclasses
import math
import os
from collections.abc import Callable, Sequence
from typing import Any, Literal

import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..._fields import check_count
from ...gradients import ESTIMATORS, Evaluators, estimate_gradients, finite_time_lyapunov
from ...integrate import SOLVERS
from ...scenes import SCENES
from ..figures import plot_gradient_variance
from ..recording import environment_record, write_csv, write_record
from ._objective import (
    POLICIES,
    active_parameters,
    build_env,
    closed_loop_step,
    initial_state,
    nominal_gain,
    nominal_parameters,
    objective,
    stage_costs,
)
from ._precision import precision_loss, variance_crossover


GRADIENT_VARIANCE_CSV_COLUMNS = (
    "scene", "case", "solver", "policy", "dtype", "horizon", "estimator", "sigma", "samples", "parameters",
    "gradient_norm", "gradient_norm_standard_error", "variance", "variance_standard_error",
    "bias", "bias_standard_error", "relative_bias", "alpha", "failed_samples",
    "reference_samples", "reference_norm", "reference_standard_error", "lyapunov_exponent",
)
"""One row per case, solver, policy, dtype, horizon, sigma and estimator.

- `gradient_norm`: the 2-norm of the estimate; `gradient_norm_standard_error`: the
  2-norm of its standard error vector, `sqrt(variance / samples)`.
- `variance`: the trace of the per-sample covariance; its standard error from the
  spread of the per-sample squared deviations.
- `bias`: `|estimate - reference|`; `bias_standard_error`: the norm that sampling noise
  alone gives it, `sqrt(variance / samples + reference variance / reference_samples)`. A
  bias within about twice this is no evidence of bias. `relative_bias`: `bias /
  reference_norm`.
- `alpha`: the weight of the first-order part (`alpha_order` rows).
- `failed_samples`: samples whose solve failed, left out of every statistic.
- `lyapunov_exponent`: the leading finite-time exponent (1/s) of the nominal trajectory
  over the row's horizon.
"""


CONTACT_GAP = 0.09
"""How far from the stop (m) the contact cases start, at 1 m/s (`GradientVarianceConfig.default`)."""


@dataclasses.dataclass(frozen=True)
class GradientVarianceConfig:
    """Everything a gradient-variance study depends on; the JSON record holds it.

    - `scene`, `scene_kwargs`: the env by its name in `SCENES` and its keywords; `case`
      names the pair in the output (default: the scene, with the keywords that set end
      stops or damping). `CartPole` is studied through `CartPoleContinuous` (a force of
      `action * force_mag` newtons, continuous, so that the cost is differentiable in it).
    - `initial_state`: the fixed start (default: `env.initial` at `seed`).
    - `solvers`: preset names (`lerax_like.SOLVERS.names`).
    - `horizons`: env steps; `sigmas`: smoothing scales; `policies`: from `POLICIES`.
    - `feedback_gain`: the nominal gain of `linear_feedback`: `"lqr"`, the discrete LQR
      gain of the cost's weights at the origin (the upright equilibrium), or `"zero"`.
      Open loop is always around zero actions.
    - `samples`: `N` per estimator; `reference_samples`: antithetic zeroth-order samples of
      the reference (a multiple of `samples`).
    - `state_weight`, `action_weight`: the cost `f = sum_k dt (state_weight |y_{k+1}|^2 +
      action_weight |a_k|^2)` (actions before the scene's clip to its bounds).
    - `dtype`: of the estimators' study ("float64" or "float32").
    - `lyapunov`, `precision`: whether to measure the exponent and the float32 digit loss;
      `precision_horizon`: the longest horizon searched for the digit loss.
    """

    scene: str = "CartPoleContinuous"
    scene_kwargs: dict[str, Any] = dataclasses.field(default_factory=dict)
    case: str | None = None
    initial_state: tuple[float, ...] | None = None
    solvers: tuple[str, ...] = ("rk4",)
    horizons: tuple[int, ...] = (10, 30, 100)
    sigmas: tuple[float, ...] = (0.05,)
    policies: tuple[str, ...] = POLICIES
    feedback_gain: Literal["lqr", "zero"] = "lqr"
    samples: int = 256
    reference_samples: int = 8192
    state_weight: float = 1.0
    action_weight: float = 0.1
    dtype: Literal["float64", "float32"] = "float64"
    seed: int = 0
    lyapunov: bool = True
    precision: bool = True
    precision_horizon: int | None = None

    def __post_init__(self):
        if self.scene not in SCENES:
            raise ValueError(f"unknown scene {self.scene!r}; known scenes: {', '.join(SCENES)}")
        for solver in self.solvers:
            SOLVERS.find(solver)  # the one message for a name that is no preset
        if not self.solvers:
            raise ValueError("solvers must name at least one solver preset")
        if not self.horizons:
            raise ValueError("horizons must hold at least one horizon")
        for horizon in self.horizons:
            check_count(horizon, "horizon")
        for sigma in self.sigmas:
            if not (math.isfinite(sigma) and sigma > 0):
                raise ValueError(f"sigma must be finite and > 0 (allowed range (0, inf)), got {sigma}")
        if not self.sigmas:
            raise ValueError("sigmas must hold at least one smoothing scale")
        for policy in self.policies:
            if policy not in POLICIES:
                raise ValueError(f"policy must be one of {POLICIES}, got {policy!r}")
        if self.feedback_gain not in ("lqr", "zero"):
            raise ValueError(f"feedback_gain must be 'lqr' or 'zero', got {self.feedback_gain!r}")
        check_count(self.samples, "samples")
        if self.samples < 2:
            raise ValueError(f"samples must be >= 2 (a variance needs two), got {self.samples}")
        check_count(self.reference_samples, "reference_samples")
        if self.reference_samples % self.samples:
            raise ValueError(
                f"reference_samples ({self.reference_samples}) must be a multiple of samples ({self.samples}): "
                "the reference reuses the estimators' compiled batch"
            )
        for name in ("state_weight", "action_weight"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be finite and >= 0 (allowed range [0, inf)), got {value}")
        if self.dtype not in ("float64", "float32"):
            raise ValueError(f"dtype must be 'float64' or 'float32', got {self.dtype!r}")
        if self.precision_horizon is not None:
            check_count(self.precision_horizon, "precision_horizon")

    @property
    def name(self) -> str:
        if self.case is not None:
            return self.case
        stiff = {k: v for k, v in self.scene_kwargs.items()
                 if k in ("end_stop_stiffness", "restitution", "joint_damping", "cart_kinetic_friction")}
        if not stiff:
            return self.scene
        return self.scene + "[" + ",".join(f"{k}={v:g}" for k, v in stiff.items()) + "]"

    @classmethod
    def default(cls, scene: str = "CartPoleContinuous", *, quick: bool = False, **overrides) -> "GradientVarianceConfig":
        """The study `lerax-like gradient-variance SCENE [--quick]` runs.

        The starts, at rest: the cart-pole's pole tilted 0.1 rad from upright, the double
        cart-pole's first pole 0.05 rad (the LQR gain of the default cost then balances
        both without saturating); a cart-pole with end stops `CONTACT_GAP` (0.09 m) from a
        stop at `track_limit = 0.5`, running into it at 1 m/s, with zero nominal feedback;
        the same with walls located as events (`restitution`, with cart friction too); the
        rolling disk launched sliding at 1 m/s with no spin, zero nominal torque.

        The gap puts the nominal impact at 0.09 s, halfway between the cost's sampling
        instants 0.08 and 0.10 s (`dt = 0.02`). The cost reads the state at the end of each
        env step, and through an impact that state jumps (the velocity reverses): where an
        impact time can cross a sampling instant, the cost itself is discontinuous in
        `theta` and every pathwise (first-order) gradient is biased, however exact, while
        the zeroth-order reference sees the jump. From 0.1 m the nominal impact falls on the
        instant 0.10 s, and half the smoothing samples bounce before it: that case is a
        property of the objective, measured apart (`benchmarks/contact_gradient_variance.py`).
        """
        settings: dict[str, Any] = dict(scene=scene)
        kwargs = dict(overrides.pop("scene_kwargs", {}))
        if scene == "CartPole":
            settings["scene"] = "CartPoleContinuous"
        if settings["scene"] == "CartPoleContinuous":
            # The same run into the end of the rail, with penalty end stops or located walls.
            if kwargs.get("end_stop_stiffness", 0) or "restitution" in kwargs:
                kwargs.setdefault("track_limit", 0.5)
                kwargs.setdefault("x_threshold", math.inf)
                if "restitution" not in kwargs:
                    # A damping ratio of about 0.1 with the cart and pole's 1.1 kg.
                    kwargs.setdefault("end_stop_damping", 0.2 * math.sqrt(kwargs["end_stop_stiffness"]))
                settings.update(
                    initial_state=(float(kwargs["track_limit"]) - CONTACT_GAP, 1.0, 0.0, 0.0),
                    solvers=("tsit5",),
                    feedback_gain="zero",
                )
            else:
                settings.update(initial_state=(0.0, 0.0, 0.1, 0.0))
        elif settings["scene"] == "DoubleCartPole":
            settings.update(initial_state=(0.0, 0.05, 0.0, 0.0, 0.0, 0.0))
        elif settings["scene"] == "RollingDisk":
            settings.update(initial_state=(0.0, float(kwargs.get("radius", 0.1)), 0.0, 1.0, 0.0, 0.0),
                            solvers=("tsit5",), feedback_gain="zero")
        settings["scene_kwargs"] = kwargs
        if quick:
            settings.update(horizons=(10, 30, 100), samples=256, reference_samples=8192, precision_horizon=200)
        else:
            settings.update(horizons=(10, 20, 50, 100, 200), samples=512, reference_samples=8192,
                            precision_horizon=400)
        settings.update(overrides)
        return cls(**settings)


@dataclasses.dataclass
class GradientVarianceResult:
    """A study's `rows` (see `GRADIENT_VARIANCE_CSV_COLUMNS`; each also holds its
    `estimate`) and its `record`: the configuration, the Lyapunov exponents, crossovers,
    float32 digit loss, feedback gains and the reference's description."""

    config: GradientVarianceConfig
    rows: list[dict[str, Any]]
    record: dict[str, Any]

    def write(self, out: "str | os.PathLike", **options) -> dict[str, str]:
        """`write_gradient_variance([self], out, **options)`: the CSV, the JSON record and the figure."""
        return write_gradient_variance([self], out, **options)


def run_gradient_variance(config: GradientVarianceConfig, *, progress: Callable[[str], None] | None = None) -> GradientVarianceResult:
    """Run `config`: the estimators per solver, policy, horizon and sigma; the Lyapunov
    exponents, crossovers and float32 digit loss (see `lerax_like.analysis.gradient_variance`).

    Computed with float64 enabled (the estimators' own arithmetic in `config.dtype`).
    """
    progress = progress or (lambda message: None)
    rows: list[dict[str, Any]] = []
    record: dict[str, Any] = {"lyapunov": [], "crossover": [], "precision": [], "feedback_gains": {},
                              "compile_seconds": {}}
    longest = max(config.horizons)
    key = jr.key(config.seed)
    with jax.enable_x64(True):
        for solver in config.solvers:
            env = build_env(config.scene, config.scene_kwargs, solver, config.dtype)
            env64 = build_env(config.scene, config.scene_kwargs, solver, "float64")
            y0 = initial_state(env, config.initial_state, config.seed)
            y0_64 = initial_state(env64, config.initial_state, config.seed)
            gain = nominal_gain(env64, config.feedback_gain, config.state_weight, config.action_weight)
            record["feedback_gains"][solver] = gain.tolist()
            for kind in config.policies:
                exponents = None
                if config.lyapunov:
                    theta = nominal_parameters(env64, kind, longest, jnp.asarray(gain))
                    step = closed_loop_step(env64, kind, theta)
                    exponents = np.asarray(finite_time_lyapunov(step, y0_64, longest, env64.dt))
                    record["lyapunov"].append({
                        "solver": solver, "policy": kind,
                        "leading_exponent": np.max(exponents, axis=1).tolist(),
                        "exponents_at_longest": exponents[-1].tolist(),
                    })
                f = objective(stage_costs(env, y0, kind, longest, config.state_weight, config.action_weight))
                evaluators = Evaluators(f)
                theta = nominal_parameters(env, kind, longest, jnp.asarray(gain))
                for horizon in config.horizons:
                    progress(f"{config.name} {solver} {kind} H={horizon}")
                    active = active_parameters(kind, theta, horizon)
                    for sigma in config.sigmas:
                        key, sample_key = jr.split(key)
                        estimates = estimate_gradients(
                            f, theta, active, horizon, sigma, samples=config.samples,
                            reference_samples=config.reference_samples, key=sample_key, evaluators=evaluators,
                        )
                        lyapunov_exponent = math.nan if exponents is None else float(np.max(exponents[horizon - 1]))
                        labels = dict(scene=config.scene, case=config.name, solver=solver, policy=kind,
                                      dtype=config.dtype, horizon=horizon, sigma=sigma)
                        rows += [_estimator_row(labels, name, estimates, int(active.sum()), lyapunov_exponent)
                                 for name in ESTIMATORS]
                record["compile_seconds"][f"{solver}/{kind}"] = evaluators.compile_seconds
                if exponents is not None and len(config.horizons) > 1:
                    record["crossover"] += _crossovers(rows, solver, kind, config.sigmas, config.horizons,
                                                       float(np.max(exponents[-1])), float(env64.dt))
                if config.precision:
                    progress(f"{config.name} {solver} {kind} float32 vs float64")
                    envs = {}
                    for dtype in ("float64", "float32"):
                        env_of_dtype = build_env(config.scene, config.scene_kwargs, solver, dtype)
                        envs[dtype] = (env_of_dtype, initial_state(env_of_dtype, config.initial_state, config.seed))
                    record["precision"].append(precision_loss(
                        envs, solver, kind, gain, config.precision_horizon or longest,
                        state_weight=config.state_weight, action_weight=config.action_weight,
                    ))
        record = {
            "config": {**dataclasses.asdict(config), "case": config.name},
            "dt": float(build_env(config.scene, config.scene_kwargs, config.solvers[0], "float64").dt),
            **DESCRIPTIONS,
            **record,
            "environment": environment_record(),
        }
    return GradientVarianceResult(config=config, rows=rows, record=record)


DESCRIPTIONS = {
    "objective": (
        "F(theta) = E_w f(theta + sigma w), w ~ N(0, I); f = sum_k dt (state_weight |y_{k+1}|^2 + "
        "action_weight |a_k|^2) over H env steps from initial_state, through env.transition "
        "(the scene's physical input and solver), no termination"
    ),
    "policies": {
        "open_loop": "a_k = theta[k], theta of shape (H, m), around zero actions",
        "linear_feedback": "a_k = theta @ y_k, theta of shape (m, n), around the nominal gain",
    },
    "reference": (
        "antithetic zeroth order, mean of (f(theta + sigma w) - f(theta - sigma w)) w / (2 sigma) over "
        "reference_samples draws independent of the estimators': unbiased for grad F by Stein's lemma "
        "whether or not f is differentiable, and free of the simulator's derivative, so that it can "
        "expose a bias of the first-order estimator"
    ),
}
"""What the study's objective, policies and reference are, in words, for its JSON record."""


def _estimator_row(
    labels: dict[str, Any], name: str, estimates: dict[str, Any], parameters: int, lyapunov_exponent: float
) -> dict[str, Any]:
    """The row of estimator `name` (columns as `GRADIENT_VARIANCE_CSV_COLUMNS`, and its `estimate`)."""
    estimate, reference = estimates[name], estimates["reference"]
    bias = float(np.linalg.norm(estimate["mean"] - reference["mean"]))
    return {
        **labels,
        "estimator": name,
        "samples": estimate["samples"],
        "parameters": parameters,
        "gradient_norm": estimate["gradient_norm"],
        "gradient_norm_standard_error": estimate["gradient_norm_standard_error"],
        "variance": estimate["variance"],
        "variance_standard_error": estimate["variance_standard_error"],
        "bias": bias,
        # The norm that sampling noise alone gives the bias.
        "bias_standard_error": math.sqrt(estimate["variance"] / estimate["samples"]
                                         + reference["variance"] / reference["samples"]),
        "relative_bias": bias / reference["gradient_norm"] if reference["gradient_norm"] > 0 else math.nan,
        "alpha": estimate.get("alpha", math.nan),
        "failed_samples": estimate["failed_samples"],
        "reference_samples": reference["samples"],
        "reference_norm": reference["gradient_norm"],
        "reference_standard_error": reference["gradient_norm_standard_error"],
        "lyapunov_exponent": lyapunov_exponent,
        "estimate": estimate["mean"].tolist(),
    }


def _crossovers(
    rows, solver: str, kind: str, sigmas: Sequence[float], horizons: Sequence[int], exponent: float, dt: float
) -> list[dict[str, Any]]:
    """`variance_crossover` of one solver and policy, per sigma, from its rows."""
    out = []
    for sigma in sigmas:
        def variances(name):
            return [next(r["variance"] for r in rows if r["solver"] == solver and r["policy"] == kind
                         and r["sigma"] == sigma and r["horizon"] == h and r["estimator"] == name)
                    for h in horizons]

        out.append({
            "solver": solver, "policy": kind, "sigma": sigma, "horizons": list(horizons),
            **variance_crossover(horizons, variances("first_order"), variances("zeroth_order"), exponent, dt),
        })
    return out


def summary(result: GradientVarianceResult) -> list[dict[str, Any]]:
    """The study's answers in a few numbers, per solver and policy (for the JSON and the terminal).

    - `first_order_below_zeroth_order`: the horizons (per sigma) where the first-order
      variance is the smaller;
    - `first_order_variance_growth`: its ratio from the shortest to the longest horizon;
    - `largest_bias_in_standard_errors`: the first-order bias over its standard error, at
      its largest over horizons and sigmas;
    - the crossover and the float32 digit loss.
    """
    config = result.config
    out = []
    for solver in config.solvers:
        for kind in config.policies:
            rows = [r for r in result.rows if r["solver"] == solver and r["policy"] == kind]
            first = [r for r in rows if r["estimator"] == "first_order"]
            zeroth = {(r["sigma"], r["horizon"]): r for r in rows if r["estimator"] == "zeroth_order"}
            entry: dict[str, Any] = {"case": config.name, "solver": solver, "policy": kind}
            entry["first_order_below_zeroth_order"] = {
                str(sigma): [r["horizon"] for r in first if r["sigma"] == sigma
                             and r["variance"] < zeroth[(sigma, r["horizon"])]["variance"]]
                for sigma in config.sigmas
            }
            growth = {}
            for sigma in config.sigmas:
                line = sorted((r["horizon"], r["variance"]) for r in first if r["sigma"] == sigma)
                growth[str(sigma)] = line[-1][1] / line[0][1]
            entry["first_order_variance_growth"] = growth
            worst = max(first, key=lambda r: r["bias"] / r["bias_standard_error"])
            entry["largest_bias_in_standard_errors"] = {
                "ratio": worst["bias"] / worst["bias_standard_error"], "horizon": worst["horizon"],
                "sigma": worst["sigma"], "bias": worst["bias"], "bias_standard_error": worst["bias_standard_error"],
                "relative_bias": worst["relative_bias"],
            }
            entry["crossover"] = [
                {k: c[k] for k in ("sigma", "measured_horizon", "predicted_horizon", "agree", "lyapunov_exponent",
                                   "variance_growth_rate")}
                for c in result.record["crossover"] if c["solver"] == solver and c["policy"] == kind
            ]
            for p in result.record["precision"]:
                if p["solver"] == solver and p["policy"] == kind:
                    entry["float32_first_digit_lost_horizon"] = p["first_digit_lost_horizon"]
                    entry["float32_horizons_searched"] = p["horizons_searched"]
                    entry["float32_relative_error_at_longest"] = p["relative_error"][-1]
            out.append(entry)
    return out


def file_stem(name: str) -> str:
    """A case name as a file name: `CartPoleContinuous[end_stop_stiffness=10000]` ->
    `CartPoleContinuous_end_stop_stiffness_10000`."""
    return "_".join(part for part in "".join(c if c.isalnum() or c in "._-" else " " for c in name).split())


def write_gradient_variance(
    results: Sequence[GradientVarianceResult], out, *, stem: str = "gradient_variance", plot: bool = True, **extra
) -> dict[str, str]:
    """Write all `results` into `<stem>.csv` and `<stem>.json` in `out`, and (if `plot`)
    one `<stem>_<case>.png` per result. Returns the paths written, by name."""
    os.makedirs(out, exist_ok=True)
    base = os.path.join(out, stem)
    paths = {"csv": base + ".csv", "json": base + ".json"}
    write_csv([row for result in results for row in result.rows], paths["csv"], columns=GRADIENT_VARIANCE_CSV_COLUMNS)
    record = {
        "summary": [entry for result in results for entry in summary(result)],
        "cases": [{**result.record, "rows": result.rows} for result in results],
        **extra,
    }
    write_record(record, paths["json"])
    if plot:
        for result in results:
            name = f"png:{result.config.name}"
            paths[name] = f"{base}_{file_stem(result.config.name)}.png" if len(results) > 1 else base + ".png"
            plot_gradient_variance(result, paths[name])
    return paths
