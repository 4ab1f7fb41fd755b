"""Input the Gymnasium and SB3 layers refuse by name: actions, reset options, assigned states.

Non-finite input never reaches the solver: a NaN or infinite continuous action, start
bounds beyond float32's range (the observations' dtype) or NaN, an assigned state with a
NaN are refused with a `ValueError` that names what was wrong, before anything changes.
A bad discrete action is a `ValueError` naming the action, raised explicitly (not an
`assert`), so that it holds under `python -O`.
"""

import importlib.util
import os
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

import lerax_like
from lerax_like.gym import SPECS


# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)
CONTINUOUS_IDS = tuple(env_id for env_id in ALL_IDS if isinstance(SPECS[env_id].scene().action_space, lerax_like.Box))
NON_FINITE = (np.nan, np.inf, -np.inf)


def _vector(env_id, num_envs=3, **kwargs):
    return gymnasium.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **kwargs)


def test_the_continuous_ids_are_found():
    assert {"lerax_like/Pendulum-v1", "lerax_like/MountainCarContinuous-v0"} <= set(CONTINUOUS_IDS)


@pytest.mark.parametrize("value", NON_FINITE)
@pytest.mark.parametrize("env_id", CONTINUOUS_IDS)
def test_a_non_finite_action_is_refused_naming_the_action_and_the_space(env_id, value):
    env = gymnasium.make(env_id)  # with Gymnasium's wrappers (the order checker, the time limit)
    env.reset(seed=0)
    before = env.unwrapped.state.copy()
    with pytest.raises(ValueError, match=r"action \[(nan|inf|-inf)\] is not in Box\(.*\): it must be finite"):
        env.step(np.array([value]))
    np.testing.assert_array_equal(env.unwrapped.state, before)
    _, _, terminated, _, info = env.step(np.array([0.5]))  # a finite action steps as ever
    assert info["action_ok"] is True and info["solver_ok"] is True and not terminated


@pytest.mark.parametrize("value", NON_FINITE)
@pytest.mark.parametrize("env_id", CONTINUOUS_IDS)
def test_a_non_finite_vector_action_is_refused_naming_the_env(env_id, value):
    vector = _vector(env_id)
    vector.reset(seed=0)
    before = vector.unwrapped.state
    actions = np.zeros((3, 1))
    actions[1, 0] = value
    with pytest.raises(ValueError, match=r"actions\[1\] = \[(nan|inf|-inf)\] is not in Box\(.*\): every action must be finite"):
        vector.step(actions)
    np.testing.assert_array_equal(vector.unwrapped.state, before)
    _, _, _, _, info = vector.step(np.zeros((3, 1)))
    assert np.all(info["action_ok"]) and np.all(info["_action_ok"])


@pytest.mark.skipif(
    importlib.util.find_spec("stable_baselines3") is None, reason="needs Stable-Baselines3: pip install stable-baselines3"
)
@pytest.mark.parametrize("env_id", CONTINUOUS_IDS)
def test_a_non_finite_sb3_action_is_refused_naming_the_env(env_id):
    venv = lerax_like.sb3.make_vec_env(env_id, n_envs=2, seed=0)
    venv.reset()
    with pytest.raises(ValueError, match=r"actions\[0\] = \[nan\] is not in Box"):
        venv.step(np.array([[np.nan], [0.0]]))
    _, _, _, infos = venv.step(np.zeros((2, 1)))
    assert all(info["action_ok"] for info in infos)


def _bad_options(env_id):
    if SPECS[env_id].declared.reset_options == "pendulum":
        return [({"x_init": np.nan}, "x_init"), ({"y_init": 1e200}, "y_init"), ({"x_init": -np.inf}, "x_init")]
    return [
        ({"low": 1e200, "high": 1e200}, "low"),
        ({"low": -0.05, "high": np.inf}, "high"),
        ({"low": np.nan, "high": 0.05}, "low"),
        ({"low": -1e39, "high": 0.0}, "low"),  # finite in float64, infinite in float32
    ]


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_non_finite_or_overflowing_reset_bounds_are_refused_naming_the_option(env_id):
    env = gymnasium.make(env_id)
    vector = _vector(env_id)
    for options, name in _bad_options(env_id):
        for each in (env, vector):
            with pytest.raises(ValueError, match=rf"reset option '{name}' must be a finite number within float32's range"):
                each.reset(seed=0, options=options)
    # Bounds at float32's edge are still taken, as Gymnasium takes them.
    if SPECS[env_id].declared.reset_options == "bounds":
        observation, _ = env.reset(seed=0, options={"low": -0.1, "high": 0.1})
        assert np.all(np.isfinite(observation))


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_an_assigned_state_with_a_nan_is_refused_naming_state(env_id):
    env = gymnasium.make(env_id).unwrapped
    env.reset(seed=0)
    before = env.state.copy()
    bad = before.copy()
    bad[0] = np.nan
    with pytest.raises(ValueError, match="state must be finite"):
        env.state = bad
    np.testing.assert_array_equal(env.state, before)
    vector = _vector(env_id).unwrapped
    vector.reset(seed=0)
    states = vector.state
    states[-1, 1] = np.inf
    with pytest.raises(ValueError, match="state must be finite"):
        vector.state = states
    assert np.all(np.isfinite(vector.state))


_UNDER_O = """
import numpy as np, gymnasium, lerax_like
assert False, "python -O drops asserts: never reached"
env = gymnasium.make("lerax_like/CartPole-v1").unwrapped
env.reset(seed=0)
for action in (2, -1, 0.5):
    try:
        env.step(action)
    except ValueError as error:
        print("refused:", error)
vector = gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="vector_entry_point")
vector.reset(seed=0)
try:
    vector.step(np.array([0, 2]))
except ValueError as error:
    print("refused:", error)
"""


@pytest.mark.slow  # a fresh interpreter imports JAX and compiles the step
def test_a_bad_discrete_action_is_a_value_error_under_python_O():
    environment = {**os.environ, "JAX_PLATFORMS": "cpu"}
    result = subprocess.run(
        [sys.executable, "-O", "-c", _UNDER_O], capture_output=True, text=True, env=environment, timeout=600,
        cwd=os.path.dirname(os.path.dirname(lerax_like.__file__)),
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines == [
        "refused: action 2 is not in Discrete(2): it must be an integer from 0 to 1",
        "refused: action -1 is not in Discrete(2): it must be an integer from 0 to 1",
        "refused: action 0.5 is not in Discrete(2): it must be an integer from 0 to 1",
        "refused: actions[1] = 2 is not in Discrete(2): every action must be an integer from 0 to 1",
    ], result.stdout
