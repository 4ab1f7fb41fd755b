"""Gradient estimators through the simulator against black-box ones (`lerax-like gradient-variance`)."""

import csv
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like.analysis.gradient_variance as gv
from lerax_like.gradients import alpha_weight, estimate_gradients, finite_time_lyapunov
from lerax_like.cli import main


def _stats(rows, estimator):
    return next(r for r in rows if r["estimator"] == estimator)


def test_estimators_and_reference_are_unbiased_on_a_known_smoothed_gradient():
    # f(theta) = sum theta^3: grad F(theta) = E[3 (theta + sigma w)^2] = 3 theta^2 + 3 sigma^2,
    # the smoothed gradient in closed form, apart from the code under test.
    theta = jnp.array([0.3, -0.7, 1.1, 0.0])
    sigma = 0.2

    def f(t, horizon):
        del horizon
        return jnp.sum(t**3), jnp.asarray(True)

    active = np.ones(4, dtype=bool)
    estimates = estimate_gradients(f, theta, active, 1, sigma, samples=512, reference_samples=8192,
                                   key=jax.random.key(1))
    exact = 3 * np.asarray(theta) ** 2 + 3 * sigma**2
    for name in ("first_order", "zeroth_order", "reference"):
        stats = estimates[name]
        error = np.linalg.norm(stats["mean"] - exact)
        assert error < 3 * math.sqrt(stats["variance"] / stats["samples"]), name
    # Per sample, the first-order gradient is less spread than the black-box estimate.
    assert estimates["first_order"]["variance"] < estimates["zeroth_order"]["variance"]


def test_alpha_order_weight_minimises_the_variance_and_guards_against_bias():
    rng = np.random.default_rng(0)
    zeroth = rng.normal(size=(4000, 3)) * 2.0
    first = rng.normal(size=(4000, 3)) * 1.0
    # Independent, unbiased: alpha = V0 / (V0 + V1) = 4 / 5.
    alpha, guarded = alpha_weight(first, zeroth)
    assert not guarded and abs(alpha - 0.8) < 0.03
    alpha, guarded = alpha_weight(first + 1.0, zeroth)
    assert guarded and alpha == 0.0


@pytest.mark.slow  # 8 to 11 s on 2 cores
def test_objective_gradient_matches_finite_differences():
    config = gv.GradientVarianceConfig.default("CartPole", quick=True)
    env = gv.build_env(config.scene, config.scene_kwargs, "rk4", config.dtype)
    y0 = gv.initial_state(env, config.initial_state, config.seed)
    gain = jnp.asarray(gv.lqr_gain(env, config.state_weight, config.action_weight))
    for kind, theta in (("open_loop", 0.1 * jnp.sin(jnp.arange(20.0))[:, None]), ("linear_feedback", gain)):
        f = jax.jit(gv.objective(gv.stage_costs(env, y0, kind, 20, config.state_weight, config.action_weight)))
        gradient = np.asarray(jax.jit(jax.grad(lambda t: f(t, 15)[0]))(theta)).reshape(-1)
        direction = jax.random.normal(jax.random.key(2), theta.shape, dtype=theta.dtype)
        h = 1e-5
        central = float((f(theta + h * direction, 15)[0] - f(theta - h * direction, 15)[0]) / (2 * h))
        assert abs(central - gradient @ np.asarray(direction).reshape(-1)) < 1e-7 * max(1.0, abs(central))
        if kind == "open_loop":
            # Steps past the horizon do not count.
            assert np.all(gradient[15:] == 0)


@pytest.mark.slow  # about 10 s on 2 cores
def test_lqr_gain_solves_the_discrete_riccati_equation():
    scipy_linalg = pytest.importorskip("scipy.linalg")
    env = gv.build_env("CartPoleContinuous", {}, "rk4", "float64")
    step = lambda y, a: gv.step_state(env, y, a)[0]  # noqa: E731
    zero_y, zero_a = jnp.zeros(4), jnp.zeros(1)
    A = np.asarray(jax.jacfwd(step)(zero_y, zero_a))
    B = np.asarray(jax.jacfwd(step, argnums=1)(zero_y, zero_a))
    dt = float(env.dt)
    Q, R = dt * np.eye(4), 0.1 * dt * np.eye(1)
    P = scipy_linalg.solve_discrete_are(A, B, Q, R)
    expected = -np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    gain = gv.lqr_gain(env, 1.0, 0.1)
    np.testing.assert_allclose(gain, expected, rtol=1e-6)
    assert np.max(np.abs(np.linalg.eigvals(A + B @ gain))) < 1


def test_lyapunov_exponent_of_the_upright_cart_pole_is_its_unstable_eigenvalue():
    # Linearised at upright with no force, theta'' = g theta / (l (4/3 - m / (M + m))): the
    # stretching rate is the square root of that rate. From a 1e-9 tilt the fall stays
    # linear for 4 s; the finite-time exponent is that rate plus a transient / T, so the
    # stretching between 2 s and 4 s gives the rate itself.
    env = gv.build_env("CartPoleContinuous", {}, "rk4", "float64")
    y0 = gv.initial_state(env, (0.0, 0.0, 1e-9, 0.0), seed=0)
    step = gv.closed_loop_step(env, "open_loop", jnp.zeros((200, 1)))
    exponents = np.asarray(finite_time_lyapunov(step, y0, 200, env.dt))
    leading = np.max(exponents, axis=1)
    rate = (leading[199] * 4.0 - leading[99] * 2.0) / 2.0
    expected = math.sqrt(9.8 / (0.5 * (4 / 3 - 0.1 / 1.1)))
    assert abs(rate - expected) < 0.01 * expected
    # The flow conserves phase-space volume: the exponents sum to about zero.
    assert abs(np.sum(exponents[-1])) < 0.01


@pytest.mark.slow  # 8 to 11 s on 2 cores
# Measures float32's rounding itself: at LLVM's opt level 0 the error after 60 steps was 3.2e-7,
# not 10 times the 8.0e-8 after one step (docs/testing.md).
@pytest.mark.xla_defaults
def test_float32_gradient_is_float32_and_loses_digits_with_the_horizon():
    config = gv.GradientVarianceConfig.default("CartPole", quick=True)
    envs = {}
    for dtype in ("float64", "float32"):
        env = gv.build_env(config.scene, config.scene_kwargs, "rk4", dtype)
        envs[dtype] = (env, gv.initial_state(env, config.initial_state, config.seed))
    entry = gv.precision_loss(envs, "rk4", "open_loop", np.zeros((1, 4)), 60, state_weight=config.state_weight,
                              action_weight=config.action_weight)
    error = np.asarray(entry["relative_error"])
    assert error.shape == (60,)
    # float32 rounding, neither float64's nor garbage, after one step ...
    assert 1e-9 < error[0] < 1e-4
    # ... growing along the fall of the pole from upright.
    assert error[-1] > 10 * error[0]


@pytest.mark.slow  # 8 to 11 s on 2 cores
def test_first_order_has_lower_variance_and_agrees_with_zeroth_order_on_cart_pole():
    # CartPole through CartPoleContinuous (a force of action * 10 N), at the shortest horizon.
    config = gv.GradientVarianceConfig.default(
        "CartPole", quick=True, horizons=(10,), policies=("open_loop", "linear_feedback"),
        lyapunov=False, precision=False, reference_samples=4096,
    )
    assert config.scene == "CartPoleContinuous"
    result = gv.run_gradient_variance(config)
    for kind in config.policies:
        rows = [r for r in result.rows if r["policy"] == kind]
        first, zeroth = _stats(rows, "first_order"), _stats(rows, "zeroth_order")
        assert first["failed_samples"] == 0
        assert first["variance"] < zeroth["variance"] / 10
        difference = np.linalg.norm(np.subtract(first["estimate"], zeroth["estimate"]))
        combined = math.hypot(first["gradient_norm_standard_error"], zeroth["gradient_norm_standard_error"])
        assert difference < 2 * combined, kind
        # And no bias against the independent reference on this smooth problem.
        assert first["bias"] < 3 * first["bias_standard_error"], kind


def test_bad_input_is_refused_with_the_parameter_named():
    with pytest.raises(ValueError, match="sigma"):
        gv.GradientVarianceConfig(sigmas=(0.0,))
    with pytest.raises(ValueError, match="solver"):
        gv.GradientVarianceConfig(solvers=("nope",))
    with pytest.raises(ValueError, match="reference_samples"):
        gv.GradientVarianceConfig(samples=100, reference_samples=150)
    with pytest.raises(ValueError, match="clips or wraps"):
        gv.build_env("Pendulum", {}, "rk4", "float64")
    assert main(["gradient-variance", "Pendulum", "--quick", "--no-plot", "--out", "unused"]) == 2


@pytest.mark.slow
def test_quick_run_on_double_cart_pole(tmp_path):
    assert main(["gradient-variance", "DoubleCartPole", "--quick", "--out", str(tmp_path), "--no-plot"]) == 0
    with open(tmp_path / "DoubleCartPole_gradient_variance.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert set(rows[0]) == set(gv.GRADIENT_VARIANCE_CSV_COLUMNS)
    first = {int(r["horizon"]): float(r["variance"]) for r in rows
             if r["policy"] == "open_loop" and r["estimator"] == "first_order"}
    # Chaos: the first-order variance grows at least tenfold from the shortest horizon to the longest.
    assert first[max(first)] > 10 * first[min(first)]
    record = json.loads((tmp_path / "DoubleCartPole_gradient_variance.json").read_text())
    open_loop = next(c for c in record["cases"][0]["lyapunov"] if c["policy"] == "open_loop")
    assert open_loop["leading_exponent"][-1] > 0
    assert {entry["policy"] for entry in record["summary"]} == {"open_loop", "linear_feedback"}


@pytest.mark.slow
def test_located_walls_give_an_unbiased_gradient_unless_an_impact_crosses_a_sampling_instant():
    # The cart runs into a located wall at 1 m/s. From the default start the impact falls
    # between the cost's sampling instants for every smoothing sample: the cost is smooth
    # there and the exact hybrid gradient is unbiased against the antithetic zeroth-order
    # reference (Stein's lemma, no derivative used). From 0.1 m the nominal impact falls on
    # the instant 0.10 s: the sampled state jumps, the cost with it, and the first-order
    # mean misses the smoothed gradient by many standard errors.
    def bias_in_standard_errors(**overrides):
        config = gv.GradientVarianceConfig.default(
            "CartPoleContinuous", scene_kwargs={"restitution": 0.8}, horizons=(10,), policies=("open_loop",),
            samples=64, reference_samples=1024, lyapunov=False, precision=False, **overrides,
        )
        row = _stats(gv.run_gradient_variance(config).rows, "first_order")
        assert row["failed_samples"] == 0
        return row["bias"] / row["bias_standard_error"]

    default = gv.GradientVarianceConfig.default("CartPoleContinuous", scene_kwargs={"restitution": 0.8})
    assert default.initial_state[0] == pytest.approx(0.5 - 0.09)  # the impact at 0.09 s, mid-step
    assert bias_in_standard_errors() < 2.5
    assert bias_in_standard_errors(initial_state=(0.4, 1.0, 0.0, 0.0)) > 4
