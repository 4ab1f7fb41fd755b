"""The gradient of the discretised env against the continuous system's, and `lerax-like gradients`."""

import csv
import json

import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.analysis import GRADIENT_CSV_COLUMNS, gradient_scenes
from lerax_like.gradients import trajectory_sensitivity, with_integrator
from lerax_like.cli import main


INF = float("inf")


def _sensitivities(integrator, steps=100):
    env = with_integrator(ll.CartPoleContinuous(theta_threshold_radians=INF, x_threshold=INF), integrator)
    y0 = jnp.array([0.0, 0.0, jnp.pi - 0.3, 0.0])
    actions = 0.5 * jnp.sin(0.1 * jnp.arange(steps, dtype=jnp.float64))[:, None]
    return np.asarray(trajectory_sensitivity(env, lambda e: e.dynamics.half_length, y0, actions)[:, 2])


@pytest.mark.slow  # 2.9 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_euler_gradient_is_first_order_and_can_have_the_wrong_sign():
    reference = _sensitivities(ll.make_integrator("rk4", substeps=8))  # ~1e-9 from Dopri8 at rtol 1e-12
    euler = _sensitivities(ll.make_integrator("euler"))
    euler_half_step = _sensitivities(ll.make_integrator("euler", substeps=2))
    # Order 1: halving the step about halves the error of the sensitivity.
    ratio = np.linalg.norm(euler - reference) / np.linalg.norm(euler_half_step - reference)
    assert 1.5 < ratio < 2.6
    # A swing from near hanging: d theta / d half_length after 92 steps (1.84 s) has the
    # opposite sign under Gymnasium's Euler at dt = 0.02, both of order 1.
    assert euler[92] * reference[92] < 0
    assert min(abs(euler[92]), abs(reference[92])) > 1.0


@pytest.mark.slow
def test_quick_gradient_study_writes_rows_at_the_solvers_orders(tmp_path):
    assert main(["gradients", "CartPole", "--quick", "--out", str(tmp_path), "--no-plot"]) == 0
    assert sorted(path.name for path in tmp_path.iterdir()) == ["CartPole_gradients.csv", "CartPole_gradients.json"]
    with open(tmp_path / "CartPole_gradients.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert set(rows[0]) == set(GRADIENT_CSV_COLUMNS)
    assert all(row["solver_ok"] == "True" and float(row["seconds"]) > 0 for row in rows)
    record = json.loads((tmp_path / "CartPole_gradients.json").read_text())
    assert {"pole_mass", "half_length"} <= set(record["parameter_names"])
    assert len(record["reference"]["gradient"]) == len(record["parameter_names"])
    assert record["reference"]["floor"] < 1e-10

    def fixed(solver):
        line = sorted((float(r["dt"]), float(r["error"])) for r in rows if r["solver"] == solver and r["dt"])
        return np.array(line).T

    euler_dt, euler_error = fixed("euler")
    rk4_dt, rk4_error = fixed("rk4")
    # Gymnasium's Euler step has a gradient error of order 1e-1; RK4 at a quarter of it,
    # far less. Each error falls with the step at the method's order (log-log slope).
    assert rk4_error[0] < 1e-4 * euler_error[-1]
    assert 0.6 < np.polyfit(np.log(euler_dt), np.log(euler_error), 1)[0] < 1.5
    assert 3.5 < np.polyfit(np.log(rk4_dt), np.log(rk4_error), 1)[0] < 4.5


def test_gradient_study_refuses_scenes_that_clip_their_state(capsys):
    assert main(["gradients", "Pendulum", "--quick", "--no-plot"]) == 2
    message = capsys.readouterr().err
    assert "Pendulum clips or wraps its state" in message and "CartPole, CartPoleContinuous" in message
    assert "Pendulum" not in gradient_scenes() and "VanDerPol" in gradient_scenes()


def _impacts_in_recorded_rollout(record) -> int:
    """The impacts of the study's own rollout (its recorded start and actions), counted by
    the env, so that a test knows the gradient it checks went through contact."""
    from lerax_like import make as make_scene

    env = make_scene(record["config"]["scene"], **record["config"]["scene_kwargs"])
    state = ll.EnvState(y=jnp.asarray(record["initial_state"]), steps=jnp.asarray(0))
    actions = jnp.asarray(record["actions"])
    if isinstance(env.action_space, ll.Discrete):
        actions = actions.astype(int)
    _, info = ll.rollout(env, state, actions)
    assert bool(jnp.all(info["solver_ok"]))
    return int(jnp.sum(info["impacts"]))


def _gradient_rows(tmp_path, scene, *arguments):
    assert main(["gradients", scene, "--quick", "--out", str(tmp_path), "--no-plot", *arguments]) == 0
    record = json.loads((tmp_path / f"{scene}_gradients.json").read_text())
    errors = {}
    for row in record["rows"]:
        assert row["solver_ok"]
        errors.setdefault(row["solver"], []).append(row["error"])
    return record, errors


@pytest.mark.slow
def test_gradient_study_through_the_ball_s_located_impacts(tmp_path):
    record, errors = _gradient_rows(tmp_path, "BouncingBall")
    assert _impacts_in_recorded_rollout(record) >= 2
    # Between impacts the ball moves under gravity and a thrust held over each step: its
    # flight is quadratic in time, which RK4 integrates exactly, so with the impacts
    # located to round-off its gradient (event times included) agrees with Dopri8's at
    # round-off too; Euler's is first order and far off.
    assert max(errors["rk4"]) < 1e-10
    assert min(errors["euler"]) > 1e-3


@pytest.mark.slow
def test_gradient_study_takes_scene_keywords_for_located_walls(tmp_path):
    keywords = ["--scene-keyword", "restitution=0.8", "--scene-keyword", "track_limit=0.1"]
    record, errors = _gradient_rows(tmp_path, "CartPoleContinuous", *keywords)
    assert record["config"]["scene_kwargs"] == {"restitution": 0.8, "track_limit": 0.1}
    assert _impacts_in_recorded_rollout(record) >= 1
    # RK4's gradient error through the walls falls with the step at about its order (4
    # substeps: 4**4 = 256 less at order 4; the quick sweep's two points are not yet in the
    # asymptotic range, so ask for more than order 3's 64).
    coarse, fine = errors["rk4"]
    assert fine < coarse / 64
    assert fine < 1e-5


def test_gradient_study_refuses_a_malformed_scene_keyword(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["gradients", "CartPoleContinuous", "--quick", "--no-plot", "--scene-keyword", "restitution"])
    assert exit_info.value.code == 2
    assert "--scene-keyword takes KEY=NUMBER" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scene", "chosen"),
    [("CartPole", ("half_length", "pole_mass")), ("SlidingBlock", ("kinetic_friction", "mass"))],
)
def test_gradient_study_of_chosen_parameters_is_the_full_study_s_entries(scene, chosen):
    """`parameters=` picks leaves of the dynamics and of a friction add-on (whose `where`
    must not unpack the add-ons: `eqx.tree_at` wraps them), in the order asked for."""
    from lerax_like.analysis import GradientStudyConfig, SolverSweep, run_gradient_study

    settings = dict(scene=scene, sweeps=(SolverSweep("rk4", substeps=(1,)),), horizon=10, repeats=1)
    every = run_gradient_study(GradientStudyConfig(**settings)).record
    some = run_gradient_study(GradientStudyConfig(**settings, parameters=chosen)).record
    # The names follow the flattened gradient (the env's leaf order), not the order asked.
    assert some["parameter_names"] == [name for name in every["parameter_names"] if name in chosen]
    full = dict(zip(every["parameter_names"], every["reference"]["gradient"]))
    # Each entry is a derivative of the same loss, by the same reference, selected differently.
    expected = [full[name] for name in some["parameter_names"]]
    np.testing.assert_allclose(some["reference"]["gradient"], expected, rtol=1e-9, atol=0)
