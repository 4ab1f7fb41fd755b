"""When do the simulator's gradients pay? Gradient variance, bias and chaos, per scene and solver.

The question of Suh, Simchowitz, Zhang and Tedrake, "Do Differentiable Simulators Give
Better Policy Gradients?" (ICML 2022), measured on this package's envs. The objective is
the Gaussian smoothing of a rollout cost,

    F(theta) = E_w[f(theta + sigma w)],  w ~ N(0, I),

where `theta` parametrises the actions over a horizon of `H` env steps (an open-loop
action sequence, or the gain of a linear state feedback) and `f` is the total quadratic
cost of the rollout from a fixed start. Two estimators of `grad F` over `N` samples:

- `first_order`: the mean of `grad f(theta + sigma w)`, the gradient through the simulator;
- `zeroth_order`: the mean of `(f(theta + sigma w) - f(theta)) w / sigma`, black box;
- `alpha_order`: the paper's interpolation `alpha first + (1 - alpha) zeroth`, with `alpha`
  chosen to minimise the variance, and 0 when the two disagree by more than three
  standard errors (the paper's guard against the first-order estimator's bias).

Each is reported with its norm, its variance (the trace of the per-sample covariance)
and its bias against a reference `grad F`, all with standard errors. The reference is a
zeroth-order estimate with antithetic samples, `(f(theta + sigma w) - f(theta - sigma w))
w / (2 sigma)`, over many samples: by Stein's lemma it is unbiased for `grad F` whether
or not `f` is differentiable, and it never uses the simulator's derivative, so it can
expose a bias of the first-order estimator (the first-order mean over many samples could
not: it would share that bias).

Beside them: the finite-time Lyapunov exponent of the nominal trajectory (QR
renormalisation of the product of the step Jacobians), the horizon past which the
first-order variance is then expected to exceed the zeroth-order one, the horizon where
it is measured to, and the horizon at which the float32 gradient has lost its leading
correct digit against float64.
"""

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from .._fields import check_count
from .._types import Array, BoolScalar, Float, Scalar
from ..env import AbstractEnv, EnvState
from ..integrate import SOLVER_PRESETS
from ..spaces import Box
from ..scenes import SCENES
from .scenes import make_scene


POLICIES: tuple[str, ...] = ("open_loop", "linear_feedback")
"""How `theta` sets the actions: `open_loop`, `a_k = theta[k]` (shape `(H, m)`);
`linear_feedback`, `a_k = theta @ y_k` (shape `(m, n)`)."""

ESTIMATORS: tuple[str, ...] = ("first_order", "zeroth_order", "alpha_order")

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


@dataclasses.dataclass(frozen=True)
class GradientVarianceConfig:
    """Everything a gradient-variance study depends on; the JSON record holds it.

    - `scene`, `scene_kwargs`: the env by its name in `SCENES` and its keywords; `case`
      names the pair in the output (default: the scene, with the keywords that set end
      stops or damping). `CartPole` is studied through `CartPoleContinuous` (a force of
      `action * force_mag` newtons, continuous, so that the cost is differentiable in it).
    - `initial_state`: the fixed start (default: `env.initial` at `seed`).
    - `solvers`: preset names (`lerax_like.SOLVER_PRESETS`).
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
            if solver not in SOLVER_PRESETS:
                raise ValueError(f"solver must be one of {SOLVER_PRESETS}, got {solver!r}")
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
        stiff = {k: v for k, v in self.scene_kwargs.items() if k in ("end_stop_stiffness", "joint_damping")}
        if not stiff:
            return self.scene
        return self.scene + "[" + ",".join(f"{k}={v:g}" for k, v in stiff.items()) + "]"

    @classmethod
    def default(cls, scene: str = "CartPoleContinuous", *, quick: bool = False, **overrides) -> "GradientVarianceConfig":
        """The study `lerax-like gradient-variance SCENE [--quick]` runs.

        The starts, at rest: the cart-pole's pole tilted 0.1 rad from upright, the double
        cart-pole's first pole 0.05 rad (the LQR gain of the default cost then balances
        both without saturating); a cart-pole with end stops 0.1 m from a stop at
        `track_limit = 0.5`, running into it at 1 m/s, with zero nominal feedback.
        """
        settings: dict[str, Any] = dict(scene=scene)
        kwargs = dict(overrides.pop("scene_kwargs", {}))
        if scene == "CartPole":
            settings["scene"] = "CartPoleContinuous"
        if settings["scene"] == "CartPoleContinuous":
            if kwargs.get("end_stop_stiffness", 0):
                kwargs.setdefault("track_limit", 0.5)
                kwargs.setdefault("x_threshold", math.inf)
                # A damping ratio of about 0.1 with the cart and pole's 1.1 kg.
                kwargs.setdefault("end_stop_damping", 0.2 * math.sqrt(kwargs["end_stop_stiffness"]))
                settings.update(
                    initial_state=(float(kwargs["track_limit"]) - 0.1, 1.0, 0.0, 0.0),
                    solvers=("tsit5",),
                    feedback_gain="zero",
                )
            else:
                settings.update(initial_state=(0.0, 0.0, 0.1, 0.0))
        elif settings["scene"] == "DoubleCartPole":
            settings.update(initial_state=(0.0, 0.05, 0.0, 0.0, 0.0, 0.0))
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


# --- the objective ------------------------------------------------------------------------


def _cast(tree, dtype):
    """Every floating-point leaf of `tree` in `dtype`."""
    return jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, tree)


def build_env(config: GradientVarianceConfig, solver: str, dtype=None) -> AbstractEnv:
    """The config's env with `solver`, its leaves in `dtype` (default: the config's)."""
    kwargs = {key: value for key, value in config.scene_kwargs.items() if key != "solver"}
    with jax.enable_x64(True):
        env = make_scene(config.scene, solver=solver, **kwargs)
    if not isinstance(env.action_space, Box):
        raise ValueError(
            f"{config.scene} has discrete actions; the gradient-variance study needs continuous ones "
            "(use CartPoleContinuous for CartPole)"
        )
    if type(env).projects_state():
        raise ValueError(
            f"{config.scene} clips or wraps its state after every step (its `project`), so the rollout "
            "cost has kinks that are no part of the physics; the study takes scenes that do not"
        )
    return _cast(env, jnp.dtype(dtype or config.dtype))


def _initial_state(env: AbstractEnv, config: GradientVarianceConfig) -> Array:
    dtype = env.dt.dtype
    if config.initial_state is None:
        return env.initial(key=jr.key(config.seed)).y.astype(dtype)
    y0 = jnp.asarray(np.asarray(config.initial_state, dtype=np.float64), dtype=dtype)
    if y0.shape != env.initial(key=jr.key(0)).y.shape:
        raise ValueError(f"initial_state must have shape {env.initial(key=jr.key(0)).y.shape}, got {y0.shape}")
    return y0


def _action_size(env: AbstractEnv) -> int:
    return int(np.prod(env.action_space.shape))


def _policy(kind: str, theta: Array, y: Array, k) -> Array:
    if kind == "open_loop":
        return theta[k]
    return theta @ y


def _step(env: AbstractEnv, y: Array, action: Array) -> tuple[Array, BoolScalar]:
    state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
    next_state, info = env.transition(state, action, key=None)
    return next_state.y, info["solver_ok"]


def stage_costs(
    env: AbstractEnv, y0: Array, kind: str, steps: int, state_weight: float, action_weight: float
) -> Callable[[Array, Any], tuple[Float[Array, " steps"], BoolScalar]]:
    """`(theta, horizon) -> ((c_0, ..., c_{steps-1}), all solves ok)`: the cost of each step.

    `c_k = dt (state_weight |y_{k+1}|^2 + action_weight |a_k|^2)` for `k < horizon` and 0
    after, so `f = sum_k c_k` is the cost over `horizon` steps. The rollout goes through
    `env.transition`, the scene's physical input and solver, without termination or reset
    (the cost is as smooth as the dynamics). `horizon` (at most `steps`) may be traced:
    one compilation serves every horizon. Past it the steps are skipped (`lax.cond` on a
    predicate that `vmap` over `theta` leaves unbatched, so the skip is real): they cost
    nothing, cannot fail, and feed nothing into the gradient.
    """

    def advance(y, action):
        next_y, step_ok = _step(env, y, jnp.reshape(action, env.action_space.shape))
        cost = env.dt * (state_weight * jnp.sum(next_y**2) + action_weight * jnp.sum(action**2))
        return next_y, step_ok, cost

    def hold(y, action):
        return y, jnp.asarray(True), jnp.zeros((), dtype=y.dtype)

    def costs(theta, horizon):
        def body(carry, k):
            y, ok = carry
            action = _policy(kind, theta, y, k)
            next_y, step_ok, cost = jax.lax.cond(k < horizon, advance, hold, y, action)
            return (next_y, ok & step_ok), cost

        (_, ok), values = jax.lax.scan(body, (y0, jnp.asarray(True)), jnp.arange(steps))
        return values, ok

    return costs


def _objective(costs):
    def f(theta, horizon):
        values, ok = costs(theta, horizon)
        return jnp.sum(values), ok

    return f


def active_parameters(kind: str, theta: Array, horizon: int) -> np.ndarray:
    """Which entries of `theta` (flattened) act within `horizon` steps: the first `horizon`
    actions of an open-loop sequence, the whole gain of a feedback policy."""
    active = np.ones(theta.shape, dtype=bool)
    if kind == "open_loop":
        active[horizon:] = False
    return active.reshape(-1)


def nominal_parameters(env: AbstractEnv, kind: str, horizon: int, gain: Array) -> Array:
    """The `theta` the study smooths around: zero actions, or the nominal feedback gain."""
    if kind == "open_loop":
        return jnp.zeros((horizon, _action_size(env)), dtype=env.dt.dtype)
    return gain.astype(env.dt.dtype)


def lqr_gain(env: AbstractEnv, state_weight: float, action_weight: float, iterations: int = 5000) -> np.ndarray:
    """The gain `G` of `a = G y` (so `G = -K`) of the discrete LQR at the origin, by Riccati iteration.

    The env step is linearised at `y = 0`, `a = 0` (the upright equilibrium of the
    cart-poles); the weights are the study cost's, `Q = state_weight dt I`, `R =
    action_weight dt I`.
    """
    n = env.initial(key=jr.key(0)).y.shape[0]
    m = _action_size(env)
    dtype = env.dt.dtype
    y = jnp.zeros((n,), dtype)
    a = jnp.zeros((m,), dtype)
    step = lambda y, a: _step(env, y, jnp.reshape(a, env.action_space.shape))[0]  # noqa: E731
    # Reverse mode: an adaptive solve's default adjoint is a custom VJP, which forward mode cannot pass.
    A = np.asarray(jax.jacrev(step, argnums=0)(y, a), dtype=np.float64)
    B = np.asarray(jax.jacrev(step, argnums=1)(y, a), dtype=np.float64)
    dt = float(env.dt)
    Q = state_weight * dt * np.eye(n) + 1e-12 * np.eye(n)
    R = max(action_weight, 1e-12) * dt * np.eye(m)
    P = Q.copy()
    for _ in range(iterations):
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P_next = Q + A.T @ P @ (A - B @ K)
        if np.allclose(P_next, P, rtol=1e-12, atol=0):
            P = P_next
            break
        P = P_next
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    return -K


# --- estimators ----------------------------------------------------------------------------


def _per_sample(estimates: np.ndarray) -> dict[str, float]:
    """Norm, variance (trace of the covariance) and their standard errors of per-sample estimates."""
    n = estimates.shape[0]
    mean = estimates.mean(axis=0)
    squared = np.sum((estimates - mean) ** 2, axis=1)
    variance = float(squared.sum() / (n - 1))
    return {
        "mean": mean,
        "gradient_norm": float(np.linalg.norm(mean)),
        "gradient_norm_standard_error": math.sqrt(variance / n),
        "variance": variance,
        "variance_standard_error": float(np.std(squared, ddof=1) / math.sqrt(n)),
        "samples": int(n),
    }


def alpha_weight(first: np.ndarray, zeroth: np.ndarray) -> tuple[float, bool]:
    """The weight of the first-order part that minimises the variance of the interpolation,
    and whether the guard set it to 0.

    With `V1`, `V0` the traces of the two per-sample covariances and `C` of their
    cross-covariance (the samples are paired), `alpha = (V0 - C) / (V1 + V0 - 2C)` in
    `[0, 1]`. The guard (Suh et al., 2022): when the two means differ by more than three
    standard errors of their difference, the first-order estimate is taken to be biased
    and `alpha = 0`.
    """
    n = first.shape[0]
    d1 = first - first.mean(axis=0)
    d0 = zeroth - zeroth.mean(axis=0)
    v1 = np.sum(d1**2) / (n - 1)
    v0 = np.sum(d0**2) / (n - 1)
    c = np.sum(d1 * d0) / (n - 1)
    difference = first - zeroth
    spread = np.sum((difference - difference.mean(axis=0)) ** 2) / (n - 1)
    if np.linalg.norm(difference.mean(axis=0)) > 3 * math.sqrt(spread / n):
        return 0.0, True
    denominator = v1 + v0 - 2 * c
    alpha = 1.0 if denominator <= 0 else float(np.clip((v0 - c) / denominator, 0.0, 1.0))
    return alpha, False


class _Evaluators:
    """`f` and `(f, grad f)` over a batch of `theta` at one `horizon`, compiled once for
    every horizon up to the objective's `steps` (the horizon is traced)."""

    def __init__(self, f):
        self._jitted = {
            "values": jax.jit(jax.vmap(f, in_axes=(0, None))),
            "gradients": jax.jit(jax.vmap(jax.value_and_grad(f, has_aux=True), in_axes=(0, None))),
        }
        self._compiled: dict[str, Any] = {}
        self.compile_seconds = 0.0

    def __call__(self, which: str, thetas: Array, horizon):
        horizon = jnp.asarray(horizon, dtype=int)
        if which not in self._compiled:
            start = time.perf_counter()
            self._compiled[which] = self._jitted[which].lower(thetas, horizon).compile()
            self.compile_seconds += time.perf_counter() - start
        return self._compiled[which](thetas, horizon)


def estimate_gradients(
    f: Callable[[Array, Any], tuple[Scalar, BoolScalar]],
    theta: Array,
    active: np.ndarray,
    horizon: int,
    sigma: float,
    *,
    samples: int,
    reference_samples: int,
    key,
    evaluators: _Evaluators | None = None,
) -> dict[str, Any]:
    """The three estimators of `grad F` at `theta` over `samples` draws, and the reference.

    `f(theta, horizon)` is the objective, `active` (flattened `theta`'s shape) marks the
    entries that act within `horizon`: only those are perturbed and estimated. Returns
    `{"first_order", "zeroth_order", "alpha_order", "reference"}`, each a dict of
    `_per_sample` statistics (`mean` is the estimate over the active entries) and
    `failed_samples`, and for `alpha_order` its `alpha` and whether the guard set it. The
    zeroth-order estimator uses the values `f(theta + sigma w)` that the first-order
    evaluation returns beside the gradients, at the same draws.
    """
    evaluators = evaluators or _Evaluators(f)
    dtype = theta.dtype
    estimator_key, reference_key = jr.split(key)
    mask = jnp.asarray(active.reshape(theta.shape), dtype=dtype)
    sigma_ = jnp.asarray(sigma, dtype=dtype)

    def draw(draw_key):
        return jr.normal(draw_key, (samples, *theta.shape), dtype=dtype) * mask

    def flat(x):
        return np.asarray(x, dtype=np.float64).reshape(x.shape[0], -1)[:, active]

    # At the compiled batch size, which the reference reuses: one compilation.
    f0, ok0 = evaluators("values", jnp.broadcast_to(theta, (samples, *theta.shape)), horizon)
    if not bool(ok0[0]):
        raise RuntimeError("the solve of the nominal rollout failed; check the solver and the scene's settings")
    f0 = float(f0[0])

    noise = draw(estimator_key)
    (values, ok), gradients = evaluators("gradients", theta + sigma_ * noise, horizon)
    ok = np.asarray(ok, dtype=bool)
    first = flat(gradients)[ok]
    zeroth = ((np.asarray(values, dtype=np.float64) - f0)[:, None] * flat(noise) / sigma)[ok]
    failed = int(np.sum(~ok))
    if first.shape[0] < 2:
        raise RuntimeError(f"{failed} of {samples} sample solves failed; too few left for a variance")

    # The reference: antithetic zeroth order, in batches of the compiled size.
    reference_estimates = []
    reference_failed = 0
    for batch_key in jr.split(reference_key, reference_samples // samples):
        w = draw(batch_key)
        plus, ok_plus = evaluators("values", theta + sigma_ * w, horizon)
        minus, ok_minus = evaluators("values", theta - sigma_ * w, horizon)
        good = np.asarray(ok_plus & ok_minus, dtype=bool)
        reference_failed += int(np.sum(~good))
        difference = (np.asarray(plus, dtype=np.float64) - np.asarray(minus, dtype=np.float64))[:, None]
        reference_estimates.append((difference * flat(w) / (2 * sigma))[good])
    reference = np.concatenate(reference_estimates)

    alpha, guarded = alpha_weight(first, zeroth)
    results = {
        "first_order": _per_sample(first),
        "zeroth_order": _per_sample(zeroth),
        "alpha_order": {**_per_sample(alpha * first + (1 - alpha) * zeroth), "alpha": alpha, "guarded": guarded},
        "reference": {**_per_sample(reference), "failed_samples": reference_failed},
    }
    for name in ESTIMATORS:
        results[name]["failed_samples"] = failed
    return results


# --- Lyapunov exponent and precision --------------------------------------------------------


def finite_time_lyapunov(
    env: AbstractEnv, y0: Array, kind: str, theta: Array, horizon: int
) -> Float[Array, "H n"]:
    """Finite-time Lyapunov exponents (1/s) of the closed-loop step map along the nominal
    trajectory, after each of `horizon` steps: row `k` holds the `n` exponents over
    `k + 1` steps.

    The tangent map `J_k = d y_{k+1} / d y_k` (the policy's feedback included) is
    propagated with QR renormalisation (Benettin et al., 1980): `J_k Q_k = Q_{k+1}
    R_{k+1}`, and the exponents are the running sums of `log |diag R|` over elapsed time.
    """
    n = y0.shape[0]

    def step(y, k):
        action = _policy(kind, theta, y, k)
        return _step(env, y, jnp.reshape(action, env.action_space.shape))[0]

    def body(carry, k):
        y, Q, logs = carry
        J = jax.jacrev(step)(y, k)  # reverse: forward mode cannot pass an adaptive solve's custom VJP
        Q, R = jnp.linalg.qr(J @ Q)
        signs = jnp.sign(jnp.diag(R))
        Q = Q * jnp.where(signs == 0, 1.0, signs)
        logs = logs + jnp.log(jnp.abs(jnp.diag(R)))
        return (step(y, k), Q, logs), logs

    eye = jnp.eye(n, dtype=y0.dtype)
    _, logs = jax.jit(lambda: jax.lax.scan(body, (y0, eye, jnp.zeros((n,), y0.dtype)), jnp.arange(horizon)))()
    elapsed = env.dt * jnp.arange(1, horizon + 1, dtype=y0.dtype)
    return logs / elapsed[:, None]


def truncated_gradients(env: AbstractEnv, y0: Array, kind: str, theta: Array, horizon: int, config) -> np.ndarray:
    """Row `h - 1`: the gradient of `f` over the first `h` steps, for every `h <= horizon`.

    One reverse-mode Jacobian of the running cost: open loop, `theta` has `horizon` steps
    and row `h - 1` is zero beyond step `h - 1`.
    """
    costs = stage_costs(env, y0, kind, horizon, config.state_weight, config.action_weight)
    running = lambda t: jnp.cumsum(costs(t, horizon)[0])  # noqa: E731
    jacobian = jax.jit(jax.jacrev(running))(theta)
    return np.asarray(jacobian, dtype=np.float64).reshape(horizon, -1)


def _relative_errors(exact: np.ndarray, approximate: np.ndarray) -> np.ndarray:
    """Row by row, `|approximate - exact| / |exact|`; infinite where that is not finite."""
    scale = np.linalg.norm(exact, axis=1)
    error = np.linalg.norm(approximate - exact, axis=1) / np.where(scale > 0, scale, np.nan)
    return np.where(np.isfinite(error), error, np.inf)


def nominal_gain(config: GradientVarianceConfig, env64: AbstractEnv) -> np.ndarray:
    """The feedback gain the linear policy smooths around: the LQR gain of `env64` (the
    config's env in float64), or zero (`feedback_gain="zero"`)."""
    if config.feedback_gain == "lqr":
        return lqr_gain(env64, config.state_weight, config.action_weight)
    return np.zeros((_action_size(env64), _initial_state(env64, config).shape[0]))


def precision_loss(config: GradientVarianceConfig, solver: str, kind: str, gain64: np.ndarray) -> dict[str, Any]:
    """float32 against float64: the relative error of the float32 gradient at the nominal
    `theta` for every horizon up to `precision_horizon`, and the horizons at which its
    correct digits (`-log10` of the relative error) fall below 6, 4, 2 and 1.

    "Lost its leading correct digit" is a relative error above 0.1.
    """
    horizon = config.precision_horizon or max(config.horizons)
    gradients = {}
    for dtype in ("float64", "float32"):
        env = build_env(config, solver, dtype)
        y0 = _initial_state(env, config)
        theta = nominal_parameters(env, kind, horizon, jnp.asarray(gain64))
        gradients[dtype] = truncated_gradients(env, y0, kind, theta, horizon, config)
    error = _relative_errors(gradients["float64"], gradients["float32"])
    digits = -np.log10(np.maximum(error, 1e-300))

    def first_below(threshold):
        index = np.nonzero(digits < threshold)[0]
        return int(index[0]) + 1 if index.size else None

    return {
        "solver": solver,
        "policy": kind,
        "horizons_searched": horizon,
        "relative_error": error.tolist(),
        "first_digit_lost_horizon": first_below(1.0),
        "digits_below_horizon": {str(t): first_below(t) for t in (6, 4, 2, 1)},
    }


def precision_at_horizons(
    config: GradientVarianceConfig, solver: str, kind: str, gain64: np.ndarray, horizons: Sequence[int]
) -> dict[str, Any]:
    """float32 against float64 at the given horizons only: the gradient of `f` over each
    horizon, one reverse pass per horizon and dtype, its relative error, the first of
    `horizons` at which the float32 gradient has lost its leading correct digit (relative
    error above 0.1, or a non-finite gradient), and whether every solve of each rollout
    succeeded (a failed solve holds its state: see `stage_costs`).

    `precision_loss` does every horizon up to the longest with one Jacobian of the running
    cost; that Jacobian needs as many reverse passes as steps, which through adaptive
    solves (the end stops' Tsit5) takes minutes per policy. This costs `len(horizons)`.
    Run it with float64 enabled (as `run_gradient_variance` runs).
    """
    horizons = sorted(int(h) for h in horizons)
    gradients, solves_ok = {}, {}
    for dtype in ("float64", "float32"):
        env = build_env(config, solver, dtype)
        y0 = _initial_state(env, config)
        theta = nominal_parameters(env, kind, horizons[-1], jnp.asarray(gain64))
        costs = stage_costs(env, y0, kind, horizons[-1], config.state_weight, config.action_weight)
        value_and_gradient = jax.jit(jax.value_and_grad(_objective(costs), has_aux=True))
        results = [value_and_gradient(theta, h) for h in horizons]
        gradients[dtype] = np.stack([np.asarray(g, dtype=np.float64).ravel() for (_, _), g in results])
        solves_ok[dtype] = [bool(ok) for (_, ok), _ in results]
    error = _relative_errors(gradients["float64"], gradients["float32"])
    lost = [h for h, e in zip(horizons, error) if e > 0.1]
    return {
        "solver": solver,
        "policy": kind,
        "horizons": horizons,
        "relative_error": error.tolist(),
        "first_digit_lost_horizon": lost[0] if lost else None,
        "float64_solves_ok": solves_ok["float64"],
        "float32_solves_ok": solves_ok["float32"],
    }


def _crossing(horizons: Sequence[float], log_difference: Sequence[float]) -> float | None:
    """The horizon where `log_difference` first turns positive (log-linear interpolation),
    the first horizon if it already is, None if it never does."""
    if log_difference[0] >= 0:
        return float(horizons[0])
    for (h0, d0), (h1, d1) in zip(zip(horizons, log_difference), zip(horizons[1:], log_difference[1:])):
        if d1 >= 0:
            return float(h0 + (h1 - h0) * (-d0) / (d1 - d0))
    return None


def variance_crossover(
    horizons: Sequence[int], first: Sequence[float], zeroth: Sequence[float], exponent: float, dt: float
) -> dict[str, Any]:
    """Where the first-order variance overtakes the zeroth-order one: measured, and
    predicted from the Lyapunov exponent.

    The prediction takes the first-order variance at the shortest horizon and lets it grow
    like `exp(2 lambda t)` (a gradient through a flow grows with its tangent map), against
    the measured zeroth-order variance (interpolated between horizons). The measured
    growth rate is the least-squares slope of `log(variance) / 2` against `t = H dt`.
    Agreement: both crossovers None, or within a factor of 2 of each other.
    """
    h = np.asarray(horizons, dtype=float)
    first = np.asarray(first, dtype=float)
    zeroth = np.asarray(zeroth, dtype=float)
    measured = _crossing(h, np.log(first) - np.log(zeroth))
    predicted_first = np.log(first[0]) + 2 * exponent * (h - h[0]) * dt
    predicted = _crossing(h, predicted_first - np.log(zeroth))
    growth = float(np.polyfit(h * dt, 0.5 * np.log(first), 1)[0]) if len(h) > 1 else math.nan
    if measured is None or predicted is None:
        agree = measured is None and predicted is None
    else:
        agree = bool(max(measured, predicted) <= 2 * min(measured, predicted))
    return {
        "measured_horizon": measured,
        "predicted_horizon": predicted,
        "agree": agree,
        "lyapunov_exponent": exponent,
        "variance_growth_rate": growth,
    }


# --- the study ----------------------------------------------------------------------------


def run_gradient_variance(config: GradientVarianceConfig, *, progress: Callable[[str], None] | None = None) -> GradientVarianceResult:
    """Run `config`: the estimators per solver, policy, horizon and sigma; the Lyapunov
    exponents, crossovers and float32 digit loss (see the module docstring).

    Computed with float64 enabled (the estimators' own arithmetic in `config.dtype`).
    """
    with jax.enable_x64(True):
        return _run(config, progress or (lambda message: None))


def _run(config: GradientVarianceConfig, progress) -> GradientVarianceResult:
    rows: list[dict[str, Any]] = []
    lyapunov: list[dict[str, Any]] = []
    crossovers: list[dict[str, Any]] = []
    precision: list[dict[str, Any]] = []
    gains: dict[str, list] = {}
    compile_seconds: dict[str, float] = {}
    longest = max(config.horizons)
    key = jr.key(config.seed)
    for solver in config.solvers:
        env = build_env(config, solver)
        env64 = build_env(config, solver, "float64")
        y0 = _initial_state(env, config)
        gain = nominal_gain(config, env64)
        gains[solver] = gain.tolist()
        for kind in config.policies:
            exponents = None
            if config.lyapunov:
                theta = nominal_parameters(env64, kind, longest, jnp.asarray(gain))
                exponents = np.asarray(finite_time_lyapunov(env64, _initial_state(env64, config), kind, theta, longest))
                lyapunov.append({
                    "solver": solver, "policy": kind,
                    "leading_exponent": np.max(exponents, axis=1).tolist(),
                    "exponents_at_longest": exponents[-1].tolist(),
                })
            costs = stage_costs(env, y0, kind, longest, config.state_weight, config.action_weight)
            f = _objective(costs)
            evaluators = _Evaluators(f)
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
                    reference = estimates["reference"]
                    for name in ESTIMATORS:
                        estimate = estimates[name]
                        bias = float(np.linalg.norm(estimate["mean"] - reference["mean"]))
                        bias_se = math.sqrt(estimate["variance"] / estimate["samples"]
                                            + reference["variance"] / reference["samples"])
                        rows.append({
                            "scene": config.scene, "case": config.name, "solver": solver, "policy": kind,
                            "dtype": config.dtype, "horizon": horizon, "estimator": name, "sigma": sigma,
                            "samples": estimate["samples"], "parameters": int(active.sum()),
                            "gradient_norm": estimate["gradient_norm"],
                            "gradient_norm_standard_error": estimate["gradient_norm_standard_error"],
                            "variance": estimate["variance"],
                            "variance_standard_error": estimate["variance_standard_error"],
                            "bias": bias, "bias_standard_error": bias_se,
                            "relative_bias": bias / reference["gradient_norm"] if reference["gradient_norm"] > 0 else math.nan,
                            "alpha": estimate.get("alpha", math.nan),
                            "failed_samples": estimate["failed_samples"],
                            "reference_samples": reference["samples"],
                            "reference_norm": reference["gradient_norm"],
                            "reference_standard_error": reference["gradient_norm_standard_error"],
                            "lyapunov_exponent": float(np.max(exponents[horizon - 1])) if exponents is not None else math.nan,
                            "estimate": estimate["mean"].tolist(),
                        })
            compile_seconds[f"{solver}/{kind}"] = evaluators.compile_seconds
            if exponents is not None and len(config.horizons) > 1:
                exponent = float(np.max(exponents[-1]))
                for sigma in config.sigmas:
                    def variances(name):
                        return [next(r["variance"] for r in rows if r["solver"] == solver and r["policy"] == kind
                                     and r["sigma"] == sigma and r["horizon"] == h and r["estimator"] == name)
                                for h in config.horizons]

                    crossovers.append({
                        "solver": solver, "policy": kind, "sigma": sigma, "horizons": list(config.horizons),
                        **variance_crossover(config.horizons, variances("first_order"), variances("zeroth_order"),
                                             exponent, float(env64.dt)),
                    })
            if config.precision:
                progress(f"{config.name} {solver} {kind} float32 vs float64")
                precision.append(precision_loss(config, solver, kind, gain))
    record = {
        "config": {**dataclasses.asdict(config), "case": config.name},
        "dt": float(build_env(config, config.solvers[0], "float64").dt),
        "objective": (
            "F(theta) = E_w f(theta + sigma w), w ~ N(0, I); f = sum_k dt (state_weight |y_{k+1}|^2 + "
            "action_weight |a_k|^2) over H env steps from initial_state, through env.transition "
            "(the scene's physical input and solver), no termination"
        ),
        "policies": {
            "open_loop": "a_k = theta[k], theta of shape (H, m), around zero actions",
            "linear_feedback": "a_k = theta @ y_k, theta of shape (m, n), around the nominal gain",
        },
        "feedback_gains": gains,
        "reference": (
            "antithetic zeroth order, mean of (f(theta + sigma w) - f(theta - sigma w)) w / (2 sigma) over "
            "reference_samples draws independent of the estimators': unbiased for grad F by Stein's lemma "
            "whether or not f is differentiable, and free of the simulator's derivative, so that it can "
            "expose a bias of the first-order estimator"
        ),
        "lyapunov": lyapunov,
        "crossover": crossovers,
        "precision": precision,
        "compile_seconds": compile_seconds,
    }
    from .study import environment_record

    record["environment"] = environment_record()
    return GradientVarianceResult(config=config, rows=rows, record=record)


# --- writing it down ----------------------------------------------------------------------


def summary(result: GradientVarianceResult) -> dict[str, Any]:
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


def format_gradient_variance_table(rows: Sequence[dict[str, Any]]) -> str:
    """A fixed-width table of the rows, for the terminal."""
    header = ("solver", "policy", "H", "sigma", "estimator", "norm", "variance", "bias (se)")
    lines = [header]
    for r in rows:
        lines.append((
            r["solver"], r["policy"], str(r["horizon"]), f"{r['sigma']:g}", r["estimator"],
            f"{r['gradient_norm']:.3g}", f"{r['variance']:.3g}", f"{r['bias']:.2g} ({r['bias_standard_error']:.2g})",
        ))
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(line, widths)).rstrip() for line in lines)


def plot_gradient_variance(result: GradientVarianceResult, path=None):
    """Variance and bias against horizon, one line per estimator and solver; float32 error.

    One row of panels per policy and sigma: the variance (log) with the first-order
    variance the Lyapunov exponent predicts (dotted); the bias with its standard error
    (the band noise alone gives); the relative error of the float32 gradient against
    float64 at the nominal `theta`. Returns the figure; saves it when `path` is given.
    """
    from .report import _finish, _pyplot

    plt = _pyplot()
    config = result.config
    panels = [(kind, sigma) for kind in config.policies for sigma in config.sigmas]
    figure, axes = plt.subplots(len(panels), 3, figsize=(15, 3.6 * len(panels)), squeeze=False)
    colours = {"first_order": "C0", "zeroth_order": "C1", "alpha_order": "C2"}
    styles = ["-", "--", ":", "-."]
    dt = result.record["dt"]
    for (kind, sigma), (variance_axis, bias_axis, precision_axis) in zip(panels, axes):
        for s, solver in enumerate(config.solvers):
            style = styles[s % len(styles)]
            for name in reversed(ESTIMATORS):  # first order on top: alpha order often equals it
                line = sorted((r for r in result.rows if r["solver"] == solver and r["policy"] == kind
                               and r["sigma"] == sigma and r["estimator"] == name), key=lambda r: r["horizon"])
                h = [r["horizon"] for r in line]
                variance_axis.errorbar(h, [r["variance"] for r in line], yerr=[r["variance_standard_error"] for r in line],
                                       color=colours[name], linestyle=style, marker="o", ms=3, label=f"{name}, {solver}")
                bias_axis.plot(h, [r["bias"] for r in line], color=colours[name], linestyle=style, marker="o", ms=3,
                               label=f"{name}, {solver}")
                bias_axis.plot(h, [r["bias_standard_error"] for r in line], color=colours[name], linestyle=style,
                               lw=0.7, alpha=0.5)
            for c in result.record["crossover"]:
                if c["solver"] == solver and c["policy"] == kind and c["sigma"] == sigma:
                    first = sorted((r["horizon"], r["variance"]) for r in result.rows if r["solver"] == solver
                                   and r["policy"] == kind and r["sigma"] == sigma and r["estimator"] == "first_order")
                    h = np.linspace(first[0][0], first[-1][0], 50)
                    predicted = first[0][1] * np.exp(2 * c["lyapunov_exponent"] * (h - first[0][0]) * dt)
                    variance_axis.plot(h, predicted, color="k", linestyle=style, lw=0.8,
                                       label=f"exp(2 lambda t), lambda = {c['lyapunov_exponent']:.2g}/s, {solver}")
            for p in result.record["precision"]:
                if p["solver"] == solver and p["policy"] == kind:
                    error = np.asarray(p["relative_error"])
                    precision_axis.semilogy(np.arange(1, len(error) + 1), np.maximum(error, 1e-17),
                                            linestyle=style, label=solver)
        variance_axis.set_yscale("log")
        bias_axis.set_yscale("log")
        variance_axis.set_ylabel("variance (trace of covariance)")
        bias_axis.set_ylabel("|estimate - reference| (thin: noise alone)")
        precision_axis.axhline(0.1, color="r", lw=0.6, label="leading digit lost")
        precision_axis.set_ylabel("float32 gradient, relative error")
        precision_axis.set_xlabel("horizon (env steps)")
        for axis in (variance_axis, bias_axis):
            axis.set_xlabel("horizon (env steps)")
        variance_axis.set_title(f"{kind}, sigma = {sigma:g}: variance", fontsize="medium")
        bias_axis.set_title(f"{kind}, sigma = {sigma:g}: bias against the reference", fontsize="medium")
        precision_axis.set_title(f"{kind}: float32 vs float64 at nominal theta", fontsize="medium")
        for axis in (variance_axis, bias_axis, precision_axis):
            axis.grid(True, which="major", alpha=0.3)
            axis.legend(fontsize="x-small")
    title = f"{config.name}: gradient estimators over {_samples_text(config)}, dt = {dt:g} s, {config.dtype}"
    return _finish(plt, figure, title, path)


def _samples_text(config: GradientVarianceConfig) -> str:
    return f"N = {config.samples} samples (reference: {config.reference_samples} antithetic)"


def file_stem(name: str) -> str:
    """A case name as a file name: `CartPoleContinuous[end_stop_stiffness=10000]` ->
    `CartPoleContinuous_end_stop_stiffness_10000`."""
    return "_".join(part for part in "".join(c if c.isalnum() or c in "._-" else " " for c in name).split())


def write_gradient_variance(
    results: Sequence[GradientVarianceResult], out, *, stem: str = "gradient_variance", plot: bool = True, **extra
) -> dict[str, str]:
    """Write all `results` into `<stem>.csv` and `<stem>.json` in `out`, and (if `plot`)
    one `<stem>_<case>.png` per result. Returns the paths written, by name."""
    import os

    from .report import _dump_json, write_csv

    os.makedirs(out, exist_ok=True)
    base = os.path.join(out, stem)
    paths = {"csv": base + ".csv", "json": base + ".json"}
    write_csv([row for result in results for row in result.rows], paths["csv"], columns=GRADIENT_VARIANCE_CSV_COLUMNS)
    record = {
        "summary": [entry for result in results for entry in summary(result)],
        "cases": [{**result.record, "rows": result.rows} for result in results],
        **extra,
    }
    _dump_json(record, paths["json"])
    if plot:
        for result in results:
            name = f"png:{result.config.name}"
            paths[name] = f"{base}_{file_stem(result.config.name)}.png" if len(results) > 1 else base + ".png"
            plot_gradient_variance(result, paths[name])
    return paths
