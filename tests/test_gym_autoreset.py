"""The vector env's three autoreset modes, step by step against Gymnasium's `SyncVectorEnv`.

For every id and mode, Gymnasium's `SyncVectorEnv` over Gymnasium's own env (the same
`autoreset_mode`, time limit, seeds and actions) is the reference: observations, rewards,
flags, states, and the infos' structure as Gymnasium builds it (`final_obs`,
`final_info` and their masks in same-step mode; which envs have a step's info at all).
Each reference env is wrapped to report `solver_ok` in its step's info, so that
Gymnasium's own bookkeeping says which envs of a step carry step info and which carry
only their reset's.

Starts are the one thing copied: Gymnasium's `SyncVectorEnv` gives each env its own
generator, while the vector env draws all starts from one, as Gymnasium's vector CartPole
does (tested in test_gym_vector and test_gym_layer). So whenever an env (re)starts, its
start is written into the reference env, and the reference's observation of it is read
from Gymnasium's env.
"""

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import lerax_like  # noqa: F401  (registers the ids)
from lerax_like.gym import SPECS


# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)
MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
NUM_ENVS = 3
TIME_LIMIT = 6

# Gymnasium's MountainCarContinuous keeps its state in float32; the others compute in float64.
RTOL = {env_id: 1e-12 for env_id in ALL_IDS} | {"lerax_like/MountainCarContinuous-v0": 1e-6}

# A state one step from the task's end, written into env 0 at the start, so that
# terminations occur besides the time limit's truncations (Pendulum never terminates).
NEAR_END = {
    "lerax_like/CartPole-v1": [2.39, 1.0, 0.2, 1.0],
    "lerax_like/Acrobot-v1": [3.1, 0.0, 0.0, 0.0],
    "lerax_like/MountainCar-v0": [0.55, 0.06],
    "lerax_like/MountainCarContinuous-v0": [0.55, 0.06],
}


class _ReportsSteps(gymnasium.Wrapper):
    """Gymnasium's env with `solver_ok` in its step's info (none in its reset's), as ours."""

    def step(self, action):
        observation, reward, terminated, truncated, info = self.env.step(action)
        return observation, reward, terminated, truncated, {**info, "solver_ok": True}


def _pair(env_id, mode):
    ours = gymnasium.make_vec(
        env_id, NUM_ENVS, vectorization_mode="vector_entry_point", autoreset_mode=mode, max_episode_steps=TIME_LIMIT
    )
    reference = gymnasium.make_vec(
        SPECS[env_id].name, NUM_ENVS, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode},
        max_episode_steps=TIME_LIMIT, wrappers=[_ReportsSteps],
    )
    assert ours.metadata["autoreset_mode"] == reference.metadata["autoreset_mode"] == mode
    return ours, reference


def _observe(env) -> np.ndarray:
    """Gymnasium's observation of its env's current state."""
    for name in ("_get_obs", "_get_ob"):  # Pendulum, Acrobot
        if hasattr(env, name):
            return getattr(env, name)()
    return np.array(env.state, dtype=np.float32)  # CartPole, the mountain cars


def _copy_starts(ours, reference, mask, ref_observation):
    """Write our (re)started envs' states into the reference; its observations of them."""
    states = ours.unwrapped.state
    for index in np.flatnonzero(mask):
        env = reference.envs[index].unwrapped
        env.state = np.array(states[:, index], dtype=np.asarray(env.state).dtype)
        ref_observation[index] = _observe(env)
    return ref_observation


def _compare(env_id, ours, reference, result, ref_result, context):
    observation, reward, terminated, truncated, info = result
    ref_observation, ref_reward, ref_terminated, ref_truncated, ref_info = ref_result
    rtol = RTOL[env_id]
    assert observation.dtype == np.float32 and observation.shape == ref_observation.shape, context
    # Agreement relative to the observation's scale, as for the states below: a float32
    # state (MountainCarContinuous) rounds its small velocity relative to its position.
    atol = rtol * np.max(np.abs(ref_observation)) + 1e-12
    np.testing.assert_allclose(observation, ref_observation, rtol=max(rtol, 2**-23), atol=atol, err_msg=context)
    np.testing.assert_allclose(reward, ref_reward, rtol=rtol, atol=1e-12, err_msg=context)
    np.testing.assert_array_equal(terminated, ref_terminated, err_msg=context)
    np.testing.assert_array_equal(truncated, ref_truncated, err_msg=context)
    # Which envs carry a step's info, as Gymnasium's bookkeeping decides it.
    np.testing.assert_array_equal(info.get("_solver_ok"), ref_info.get("_solver_ok"), err_msg=context)
    assert ("final_obs" in info) == ("final_obs" in ref_info), context
    if "final_obs" in ref_info:
        np.testing.assert_array_equal(info["_final_obs"], ref_info["_final_obs"], err_msg=context)
        np.testing.assert_array_equal(info["_final_info"], ref_info["_final_info"], err_msg=context)
        final_info, ref_final_info = info["final_info"], ref_info["final_info"]
        np.testing.assert_array_equal(final_info["_solver_ok"], ref_final_info["_solver_ok"], err_msg=context)
        for index in np.flatnonzero(ref_info["_final_obs"]):
            np.testing.assert_allclose(
                info["final_obs"][index], ref_info["final_obs"][index], rtol=max(rtol, 2**-23), atol=atol,
                err_msg=context,
            )
            assert final_info["solver_ok"][index], context
        assert all(value is None for value in info["final_obs"][~info["_final_obs"]]), context
    states = np.stack([np.asarray(env.unwrapped.state, dtype=np.float64) for env in reference.envs], axis=1)
    scale = np.max(np.abs(states))
    assert np.max(np.abs(ours.unwrapped.state - states)) <= rtol * scale, context


@pytest.mark.parametrize("mode", MODES, ids=lambda mode: mode.name)
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_autoreset_mode_steps_as_gymnasiums_sync_vector_env(env_id, mode):
    ours, reference = _pair(env_id, mode)
    observation, info = ours.reset(seed=11)
    ref_observation, _ = reference.reset(seed=11)
    assert info == {}
    ref_observation = _copy_starts(ours, reference, np.ones(NUM_ENVS, dtype=bool), ref_observation)
    np.testing.assert_allclose(observation, ref_observation, rtol=2**-23, atol=1e-12)
    if env_id in NEAR_END:
        states = ours.unwrapped.state
        # float32 values: Acrobot and MountainCarContinuous hold float32 states in Gymnasium.
        states[:, 0] = np.float32(NEAR_END[env_id])
        ours.unwrapped.state = states
        _copy_starts(ours, reference, np.eye(NUM_ENVS, dtype=bool)[0], ref_observation)
    ours.action_space.seed(5)
    ended = np.zeros(NUM_ENVS, dtype=bool)
    events = {"terminated": 0, "truncated": 0, "restarted": 0}
    for step in range(3 * TIME_LIMIT):
        context = f"{env_id} {mode.name} step {step}"
        if mode == AutoresetMode.DISABLED and ended.any():
            # Stepping an env that ended is refused (Gymnasium asserts, after stepping
            # the envs before it: not tried on the reference, which it would advance).
            before = ours.unwrapped.state
            with pytest.raises(RuntimeError, match="reset_mask"):
                ours.step(ours.action_space.sample())
            np.testing.assert_array_equal(ours.unwrapped.state, before)
            mask = ended.copy()
            observation, info = ours.reset(options={"reset_mask": mask.copy()})
            ref_observation, _ = reference.reset(options={"reset_mask": mask.copy()})
            assert info == {}
            # The envs outside the mask keep their observation; those in it start again.
            ref_observation = _copy_starts(ours, reference, mask, ref_observation)
            np.testing.assert_allclose(observation, ref_observation, rtol=2**-23, atol=1e-12, err_msg=context)
            assert np.all(ours.unwrapped.batch.steps[mask] == 0), context
            events["restarted"] += int(mask.sum())
            ended[:] = False
        # float64 actions (float32's values): Gymnasium's Pendulum squares a float32
        # action in float32 for its cost, where we compute in float64.
        actions = ours.action_space.sample()
        if actions.dtype == np.float32:
            actions = actions.astype(np.float64)
        result = ours.step(actions)
        ref_result = list(reference.step(actions))
        if mode == AutoresetMode.NEXT_STEP:
            restarted = ended  # Gymnasium restarted these envs in this step
            ref_result[0] = _copy_starts(ours, reference, restarted, ref_result[0])
            events["restarted"] += int(restarted.sum())
        elif mode == AutoresetMode.SAME_STEP:
            restarted = ref_result[2] | ref_result[3]
            ref_result[0] = _copy_starts(ours, reference, restarted, ref_result[0])
            events["restarted"] += int(restarted.sum())
        _compare(env_id, ours, reference, result, ref_result, context)
        ended = result[2] | result[3]
        events["terminated"] += int(result[2].sum())
        events["truncated"] += int(result[3].sum())
    assert events["truncated"] and events["restarted"], events
    if env_id in NEAR_END:
        assert events["terminated"], events
    ours.close()
    reference.close()


def test_autoreset_mode_is_refused_by_name():
    with pytest.raises(ValueError, match="autoreset_mode must be one of"):
        gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="vector_entry_point", autoreset_mode="later")


@pytest.mark.slow  # 4.2 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_reset_mask_is_checked_as_gymnasium_checks_it():
    ours = gymnasium.make_vec(
        "lerax_like/CartPole-v1", 2, vectorization_mode="vector_entry_point", autoreset_mode=AutoresetMode.DISABLED
    )
    ours.reset(seed=0)
    for mask, error in [
        ([True, False], TypeError),
        (np.array([True]), ValueError),
        (np.array([1, 0]), TypeError),
        (np.array([False, False]), ValueError),
    ]:
        with pytest.raises(error, match="reset_mask"):
            ours.reset(options={"reset_mask": mask})
