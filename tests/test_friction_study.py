"""The studies through Coulomb stick-slip: `lerax-like study` and `lerax-like gradients` on friction scenes.

- the SciPy reference (`lerax_like.analysis.modes_reference`: `solve_ivp` restarted at every
  located switch) against the sliding block's closed forms: a block launched at `v0` on the
  level stops at `v0 / (mu_k g)` after `v0^2 / (2 mu_k g)`; on an incline it stays at rest iff
  `tan(alpha) <= mu_s`, and above it slides with acceleration `g (sin(alpha) - mu_k cos(alpha))`;
- `lerax-like study` on `SlidingBlock` and on `CartPoleContinuous` with cart friction: errors
  against that reference, over trajectories that go through stick-slip switches (counted by the
  env's own step);
- `lerax-like gradients` on `SlidingBlock`: the friction coefficients among the parameters, the
  reference by central differences of the SciPy reference, RK4's gradient within 1e-8 of it.
"""

import csv
import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like import make as make_scene
from lerax_like.analysis.modes_reference import modes_reference_step, reference_modes
from lerax_like.cli import main


G, MU_S, MU_K = 9.81, 0.5, 0.3


def _block(**keywords):
    return ll.make("SlidingBlock", **{"static_friction": MU_S, "kinetic_friction": MU_K, "gravity": G, **keywords})


@pytest.mark.parametrize("v0", [1.5, -0.8])
def test_reference_stops_a_launched_block_at_the_closed_form_time_and_distance(v0):
    with jax.enable_x64(True):
        step = modes_reference_step(reference_modes(_block()), np.array([0.0, v0]), np.zeros(1), 1.0)
    (time, which), = step.events  # one switch: the slip ends and the block sticks
    assert time == pytest.approx(abs(v0) / (MU_K * G), rel=0, abs=1e-12)
    assert step.y[0] == pytest.approx(math.copysign(v0**2 / (2 * MU_K * G), v0), rel=0, abs=1e-12)
    assert step.y[1] == 0.0


@pytest.mark.parametrize("tangent", [0.9 * MU_S, 1.2 * MU_S])
def test_reference_holds_on_an_incline_iff_its_tangent_is_within_static_friction(tangent):
    alpha = math.atan(tangent)
    with jax.enable_x64(True):
        step = modes_reference_step(reference_modes(_block(incline=alpha)), np.zeros(2), np.zeros(1), 0.5)
    if tangent <= MU_S:
        assert step.events == [] and np.all(step.y == 0.0)
    else:
        # Released at once (read off the state at rest), sliding down against kinetic friction.
        acceleration = G * (math.sin(alpha) - MU_K * math.cos(alpha))
        np.testing.assert_allclose(step.y, [-0.5 * acceleration * 0.5**2, -acceleration * 0.5], rtol=1e-12)


def _rows(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


def _switches(env, record, schedule):
    """Switches located by the env's own step along the study's trajectories (its states and inputs)."""
    inputs = jnp.asarray(record["schedules"][schedule]["inputs"])

    def trajectory(y0):
        def body(state, u):
            state, info = env.evolve(state, u)
            return state, info["switches"]

        return jax.lax.scan(body, ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int)), inputs)[1]

    return np.asarray(jax.jit(jax.vmap(trajectory))(jnp.asarray(record["initial_states"])))


# Each scene's keywords and the RK4 substeps studied (each a compilation of the located step).
STUDIES = {
    # A push of at most 6 N against a static limit of 4.9 N: the block sticks and is released.
    "SlidingBlock": (("force_mag=6",), ("1",)),
    # Pushes of at most 4 N against a static limit of about 3.2 N, and the swinging pole's reaction.
    "CartPoleContinuous": (("cart_static_friction=0.3", "cart_kinetic_friction=0.15", "force_mag=4"), ("1", "2")),
}


@pytest.mark.slow
@pytest.mark.parametrize("scene", sorted(STUDIES))
def test_study_of_a_friction_scene_is_against_the_event_located_reference(scene, tmp_path, capsys):
    keywords, substeps = STUDIES[scene]
    arguments = ["study", scene, "--quick", "--no-plot", "--no-progress", "--solver", "rk4", "--substeps", *substeps,
                 "--horizon", "12", "--out", str(tmp_path)]
    assert main(arguments + [item for pair in keywords for item in ("--scene-keyword", pair)]) == 0
    assert "order" in capsys.readouterr().out
    rows = {(row["schedule"], int(row["substeps"])): row for row in _rows(tmp_path / f"{scene}.csv")}
    with open(tmp_path / f"{scene}.json") as file:
        record = json.load(file)
    assert record["reference"]["method"] == "DOP853"
    with jax.enable_x64(True):
        env = make_scene(scene, **{key: float(value) for key, value in (pair.split("=") for pair in keywords)})
        switches = _switches(env, record, "recorded")
    assert switches.sum() >= 2, "the study must go through stick-slip switches to test anything"
    for row in rows.values():
        assert row["solver_ok"] == "True"
        assert float(row["reference_floor"]) < 1e-11
        # Dry friction dissipates: no energy or momentum drift is reported as a solver error.
        assert row["energy_drift"] in ("", "nan") and row["momentum_drift"] in ("", "nan")
    if scene == "SlidingBlock":
        # Piecewise quadratic motion between located switches: RK4 is exact to round-off.
        assert float(rows["recorded", 1]["max_error"]) < 1e-12
    else:
        # Fourth order through the switches: halving the step divides the error by about 16.
        coarse, fine = (float(rows["recorded", n]["max_error"]) for n in (1, 2))
        assert fine < 1e-6 and 8 < coarse / fine < 32


@pytest.mark.slow
def test_gradient_study_of_the_block_is_against_differences_of_the_reference(tmp_path, capsys):
    arguments = ["gradients", "SlidingBlock", "--quick", "--no-plot", "--solver", "rk4", "--horizon", "10",
                 "--out", str(tmp_path), "--scene-keyword", "force_mag=6"]
    assert main(arguments) == 0
    assert "relative to SciPy through the switches" in capsys.readouterr().out
    with open(tmp_path / "SlidingBlock_gradients.json") as file:
        record = json.load(file)
    names = record["parameter_names"]
    assert names == ["mass", "gravity", "incline", "static_friction", "kinetic_friction"]
    reference = record["reference"]
    gradient = dict(zip(names, reference["gradient"]))
    assert abs(gradient["kinetic_friction"]) > 1e-3
    # The push is constant over each step, so a stuck block is released only where it jumps,
    # at a step's start: mu_s decides whether, never when, and the loss is flat in it.
    assert abs(gradient["static_friction"]) < 1e-9
    assert reference["floor"] < 1e-8
    # The located model's own AD (Dopri8 at rtol 1e-12, forward mode) agrees with the differences.
    assert reference["dopri8_discrepancy"] < 1e-8
    rows = _rows(tmp_path / "SlidingBlock_gradients.csv")
    assert len(rows) == 2 and all(row["solver_ok"] == "True" for row in rows)
    assert all(float(row["error"]) < 1e-8 for row in rows)
