"""The vector env's dtype option and its failed steps, against the single env and float64.

The single env (`gymnasium.make`) steps through `AbstractEnv.advance` on its own, with no
observation carried over; the vector env passes the observation it returned last. A
failed step must come out the same either way.
"""

import copy
import warnings

import gymnasium
import numpy as np
import pytest

import lerax_like  # noqa: F401  (registers the ids)
from lerax_like.gym import SPECS


# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)


def _vector(env_id, num_envs, **kwargs):
    return gymnasium.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


@pytest.mark.parametrize("assign_first", [False, True])
def test_a_failed_vector_step_returns_what_the_single_env_returns(assign_first):
    # theta_dot = 3e38 fits float32, but the step's next one does not: the observation
    # overflows, so the step fails and returns the pre-step observation.
    states = np.array([[0.01, 0.0, 0.02, 0.0], [0.0, 0.0, 0.01, 3e38], [-0.02, 0.1, 0.0, -0.1]]).T
    vector = _vector("lerax_like/CartPole-v1", 3)
    vector.reset(seed=0)
    if not assign_first:
        vector.step(np.array([0, 1, 0]))  # a step first: the carried observation is then a step's
    vector.unwrapped.state = states
    actions = np.array([1, 0, 1])
    observation, reward, terminated, truncated, info = vector.step(actions)
    for index in range(3):
        single = gymnasium.make("lerax_like/CartPole-v1").unwrapped
        single.reset(seed=0)
        single.state = states[:, index]
        ref_observation, ref_reward, ref_terminated, _, ref_info = single.step(int(actions[index]))
        np.testing.assert_array_equal(observation[index], ref_observation)
        assert reward[index] == ref_reward and terminated[index] == ref_terminated
        assert info["solver_ok"][index] == ref_info["solver_ok"]
    assert list(info["solver_ok"]) == [True, False, True]
    np.testing.assert_array_equal(observation[1], states[:, 1].astype(np.float32))  # the pre-step state's


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_float32_vector_env_follows_float64(env_id):
    num_envs = 4
    ours64 = _vector(env_id, num_envs, max_episode_steps=1000)
    ours32 = _vector(env_id, num_envs, max_episode_steps=1000, dtype="float32")
    assert ours32.unwrapped.dtype == "float32" and ours64.unwrapped.dtype == "float64"
    first64, _ = ours64.reset(seed=3)
    first32, _ = ours32.reset(seed=3)
    # The same float64 draws, rounded to float32: the observations agree to float32 precision.
    np.testing.assert_allclose(first32, first64, rtol=2**-22, atol=1e-6)
    assert ours32.unwrapped.state.dtype == np.float32 and ours64.unwrapped.state.dtype == np.float64
    ours64.action_space.seed(0)
    for _ in range(3):
        actions = ours64.action_space.sample()
        observation64, reward64, *_ = ours64.step(actions)
        observation32, reward32, *_ = ours32.step(actions)
        assert observation32.dtype == np.float32 and reward32.dtype == np.float32
        assert reward64.dtype == np.float64
        np.testing.assert_allclose(observation32, observation64, rtol=1e-4, atol=1e-5)
        np.testing.assert_allclose(reward32, reward64, rtol=1e-4, atol=1e-5)


def test_a_float32_vector_env_asks_jax_for_no_dtype_it_cannot_hold():
    # The scene is built in float64, so its time limit is an int64 leaf; a float32 layer that
    # cast it back to int64 made JAX warn and truncate to int32 at every trace. Warnings come
    # at trace time only: `substeps=7` is a configuration no other test compiles, so the
    # construction (which compiles) and the steps trace here, whatever ran before.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        vector = _vector("lerax_like/CartPole-v1", 2, dtype="float32", substeps=7, max_episode_steps=3)
        vector.reset(seed=0)
        for _ in range(4):  # past the time limit: the autoreset's restart traces too
            observation, reward, *_ = vector.step(np.array([0, 1]))
    assert observation.dtype == np.float32 and reward.dtype == np.float32


def test_bad_dtype_is_refused_by_name():
    with pytest.raises(ValueError, match="dtype must be one of"):
        _vector("lerax_like/CartPole-v1", 2, dtype="float16")


_OPTIONS = {"bounds": {"low": -0.2, "high": 0.3}, "pendulum": {"x_init": 1.0, "y_init": 0.5}}


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_restarts_draw_as_gymnasium_draws_a_start(env_id, dtype):
    # With a time limit of one step, every step restarts every env: the restart draws
    # the starts as `GymSpec.initial_state` does (checked against Gymnasium's own envs in
    # test_gym_layer), from the env's generator, with the reset's options, in one call.
    num_envs = 5
    spec = SPECS[env_id]
    options = _OPTIONS[spec.declared.reset_options]
    vector = _vector(env_id, num_envs, max_episode_steps=1, dtype=dtype)
    unwrapped = vector.unwrapped
    vector.reset(seed=4, options=options)
    vector.action_space.seed(0)
    vector.step(vector.action_space.sample())  # ends every episode
    generator = copy.deepcopy(unwrapped.np_random)
    _, reward, terminated, truncated, _ = vector.step(vector.action_space.sample())  # restarts them all
    expected = spec.initial_state(unwrapped.batch.initial_bounds, generator, options, num_envs).astype(dtype)
    assert np.all(reward == 0) and not np.any(terminated | truncated)
    np.testing.assert_array_equal(unwrapped.state, expected)
    assert unwrapped.np_random.bit_generator.state == generator.bit_generator.state


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_an_invalid_action_changes_nothing(dtype):
    ours, twin = (_vector("lerax_like/CartPole-v1", 3, dtype=dtype) for _ in range(2))
    for env in (ours, twin):
        env.reset(seed=2)
        env.step(np.array([1, 0, 1]))
    before = ours.unwrapped.state
    # Out of range, and in float32 out of int32's range (it must not wrap to 0).
    for actions in (np.array([0, 1, 2]), np.array([0, 2**32, 1]), np.array([-1, 0, 0])):
        with pytest.raises(ValueError, match="actions"):
            ours.step(actions)
        np.testing.assert_array_equal(ours.unwrapped.state, before)
    for actions in (np.array([0, 0, 1]), np.array([1, 1, 1])):
        for ours_result, twin_result in zip(ours.step(actions)[:4], twin.step(actions)[:4], strict=True):
            np.testing.assert_array_equal(ours_result, twin_result)


@pytest.mark.parametrize("with_options", [False, True])
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_starts_drawn_together_are_each_generator_s_own_start(env_id, with_options):
    # SB3's envs restart from a generator each, drawn together (`starts_each`): the same
    # numbers, bit for bit, and the same generator states, as drawing each env's start on
    # its own with `initial_state` (checked against Gymnasium's envs in test_gym_layer).
    spec = SPECS[env_id]
    bounds = _vector(env_id, 1).unwrapped.batch.initial_bounds
    options = [_OPTIONS[spec.declared.reset_options] if with_options and index == 1 else None for index in range(3)]
    generators = [np.random.default_rng(seed) for seed in (5, 6, 7)]
    twins = copy.deepcopy(generators)
    together = spec.initial_state_each(bounds, generators, options)
    alone = np.concatenate([spec.initial_state(bounds, g, o, 1) for g, o in zip(twins, options)], axis=1)
    np.testing.assert_array_equal(together, alone)
    assert [g.bit_generator.state for g in generators] == [g.bit_generator.state for g in twins]
