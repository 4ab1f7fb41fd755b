"""Rollouts recorded before the constructors became Equinox's own (issue 40), compared bit for bit.

`tests/data/rollouts_before_constructors.npz` was written at f2d3a60, before the change, by

    python tests/test_rollouts_unchanged.py --record

Every scene of the package in its default configuration, and configurations built from flat
keywords (dynamics parameters, solver settings, add-ons, Gymnasium's aliases), stepped from one
start with a fixed sequence of actions: the states, rewards and solver flags must be the same
to the last bit whatever builds the scene.
"""

import math
import pathlib
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from conftest import XLA_DEFAULTS


RECORD = pathlib.Path(__file__).parent / "data" / "rollouts_before_constructors.npz"
STEPS = 25
# Scenes registered after the recording: there is no earlier rollout of theirs to compare with.
ADDED_SINCE = {"RollingDisk"}

# name -> (scene, flat keywords)
CONFIGURATIONS: dict[str, tuple[str, dict]] = {
    **{
        name: (name, {})
        for name, scene in sorted(ll.SCENES.items())
        if scene.__module__.startswith("lerax_like.") and name not in ADDED_SINCE
    },
    "CartPole-rk4-pole_mass": ("CartPole", {"solver": "rk4", "pole_mass": 0.2}),
    "CartPole-tsit5-damping": ("CartPole", {"solver": "tsit5", "joint_damping": 0.5, "half_length": 0.6}),
    "CartPole-walls": (
        "CartPole",
        {"restitution": 0.8, "track_limit": 0.06, "x_threshold": math.inf, "solver": "tsit5"},
    ),
    "CartPoleContinuous-end-stops": (
        "CartPoleContinuous",
        {"end_stop_stiffness": 1e4, "end_stop_damping": 5.0, "track_limit": 0.04, "x_threshold": math.inf, "solver": "tsit5"},
    ),
    "CartPoleContinuous-cart-friction": (
        "CartPoleContinuous",
        {"cart_static_friction": 0.3, "cart_kinetic_friction": 0.2, "solver": "rk4", "reward": "smooth"},
    ),
    "DoubleCartPole-cart-friction": ("DoubleCartPole", {"cart_static_friction": 0.15, "cart_kinetic_friction": 0.1, "cart_mass": 1.5}),
    "Pendulum-gymnasium-g": ("Pendulum", {"g": 9.81, "max_speed": 7.0}),
    "SlidingBlock-friction": ("SlidingBlock", {"static_friction": 0.4, "kinetic_friction": 0.3}),
    "BouncingBall-restitution": ("BouncingBall", {"restitution": 0.7, "solver": "rk4"}),
    "VanDerPol-mu": ("VanDerPol", {"mu": 3.0}),
}


def build(scene: str, keywords: dict):
    return ll.make(scene, **keywords)


def rollout_of(scene: str, keywords: dict) -> dict[str, np.ndarray]:
    env = build(scene, keywords)

    def run(env, key):
        start_key, action_key = jax.random.split(key)
        state, _, _ = env.reset(key=start_key)
        actions = jax.vmap(lambda k: env.action_space.sample(key=k))(jax.random.split(action_key, STEPS))
        ys, info = ll.rollout(env, state, actions)
        return {"y0": state.y, "ys": ys, "reward": info["reward"], "solver_ok": info["solver_ok"]}

    # Compiled with XLA's defaults, whose bits the record holds (the suite compiles with less
    # optimisation, conftest.py), as a user's `eqx.filter_jit` would: the same jaxpr (test_jit_env).
    dynamic, static = eqx.partition(env, eqx.is_array)
    compiled = jax.jit(lambda dynamic, key: run(eqx.combine(dynamic, static), key), compiler_options=XLA_DEFAULTS)
    return {name: np.asarray(value) for name, value in compiled(dynamic, jax.random.key(0)).items()}


@pytest.fixture(scope="module")
def recorded():
    with np.load(RECORD) as data:
        return {key: data[key] for key in data.files}


@pytest.mark.slow
@pytest.mark.parametrize("configuration", sorted(CONFIGURATIONS))
def test_a_rollout_is_bit_for_bit_as_recorded_before_the_change(configuration, recorded):
    scene, keywords = CONFIGURATIONS[configuration]
    now = rollout_of(scene, keywords)
    for name, value in now.items():
        before = recorded[f"{configuration}/{name}"]
        assert value.dtype == before.dtype, (configuration, name)
        np.testing.assert_array_equal(value, before, err_msg=f"{configuration}: {name}")


@pytest.mark.slow  # 3.5 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_every_package_scene_has_a_recorded_default_rollout(recorded):
    """A scene added after the record has none to compare with; this names the record's scenes."""
    names = {key.split("/")[0] for key in recorded}
    assert {name for name, (_, keywords) in CONFIGURATIONS.items() if keywords} <= names


if __name__ == "__main__" and sys.argv[1:] == ["--record"]:
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_numpy_dtype_promotion", "strict")
    arrays = {}
    for configuration, (scene, keywords) in sorted(CONFIGURATIONS.items()):
        for name, value in rollout_of(scene, keywords).items():
            arrays[f"{configuration}/{name}"] = value
        print(configuration, "solver_ok:", bool(arrays[f"{configuration}/solver_ok"].all()))
    RECORD.parent.mkdir(exist_ok=True)
    np.savez_compressed(RECORD, **arrays)
