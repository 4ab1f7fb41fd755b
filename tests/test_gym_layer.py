"""The Gymnasium layer against Gymnasium's own classic-control envs, the reference.

Every number compared here comes from Gymnasium run alongside, never from our code.
"""

import os
import warnings

import gymnasium
import jax
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lerax_like
from lerax_like.gym import SPECS
from conftest import STATE_RTOL


os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # check_env also opens the "human" mode

REGISTERED = lerax_like.gym.register_envs()  # already done by the import; returns the ids
# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)


def registered(env_id: str) -> str:
    assert env_id in REGISTERED and env_id in gymnasium.registry, env_id
    return env_id


def test_import_registers_an_id_per_scene():
    # Gymnasium's five names for the scenes standing for its envs; `<scene>-v0` for the others.
    assert set(ALL_IDS) == {
        "lerax_like/CartPole-v1",
        "lerax_like/Pendulum-v1",
        "lerax_like/Acrobot-v1",
        "lerax_like/MountainCar-v0",
        "lerax_like/MountainCarContinuous-v0",
    }
    standing_for = {SPECS[env_id].scene for env_id in ALL_IDS}
    # The package's scenes (registered before the ids; a test's scene, registered later, has none).
    package = {name: scene for name, scene in lerax_like.SCENES.items() if scene.__module__.startswith("lerax_like.")}
    others = {f"lerax_like/{name}-v0" for name, scene in package.items() if scene not in standing_for}
    assert set(SPECS) == set(ALL_IDS) | others and set(REGISTERED) == set(SPECS)
    assert set(SPECS) <= set(gymnasium.registry)


def reference_id(env_id: str) -> str:
    return SPECS[env_id].name



def _sign(x: float) -> int:
    return 1 if x >= 0 else -1


# Per id: episodes as (reset seed, reset options, policy of (step, Gymnasium state, rng)),
# chosen to reach every kind of event: termination, truncation, clipping, walls, wrapping.
def _cartpole_balance(n, s, rng):
    return int(s[2] + 0.5 * s[3] + 0.01 * s[0] + 0.05 * s[1] > 0)


def _pump(n, s, rng):  # mountain cars: push along the velocity, reaches the goal
    return 2 if s[1] >= 0 else 0


def _wall(n, s, rng):  # mountain cars: swing, then roll into the left wall
    return 2 if (n < 90 and s[1] >= 0) else 0


def _continuous(policy, scale):
    # Actions out of [-1, 1] exercise the clipping of the action.
    return lambda n, s, rng: np.array([scale * (policy(n, s, rng) - 1)], dtype=np.float64)


EPISODES = {
    "lerax_like/CartPole-v1": [
        (0, None, lambda n, s, rng: int(rng.integers(2))),  # falls: terminated
        (1, {"low": -0.1, "high": 0.1}, lambda n, s, rng: int(rng.integers(2))),
        (2, None, _cartpole_balance),  # balanced: truncated at 500
    ],
    "lerax_like/Pendulum-v1": [
        # torques beyond +-2 are clipped; pumping drives the speed into its +-8 clip
        (0, None, lambda n, s, rng: np.array([3.0 * _sign(s[1])])),
        (1, {"x_init": 0.5, "y_init": 0.5}, lambda n, s, rng: rng.uniform(-3.0, 3.0, size=(1,))),
    ],
    "lerax_like/Acrobot-v1": [
        (0, None, lambda n, s, rng: 2 if s[3] >= 0 else 0),  # wraps angles, reaches the goal
        (1, None, lambda n, s, rng: int(rng.integers(3))),  # truncated at 500
    ],
    "lerax_like/MountainCar-v0": [
        (0, None, _pump),
        (1, None, _wall),
    ],
    "lerax_like/MountainCarContinuous-v0": [
        (0, None, _continuous(_pump, 1.5)),  # goal reward +100
        (1, None, _continuous(_wall, 1.0)),
    ],
}

# States at the edges, written into both envs, with the action taken from each.
EDGE_CASES = {
    "lerax_like/CartPole-v1": [([2.39, 1.0, 0.2, 1.0], 1), ([-2.39, -1.0, -0.2, -1.0], 0)],
    "lerax_like/Pendulum-v1": [([0.3, 7.99], np.array([2.0])), ([-3.1, -7.9], np.array([-5.0]))],
    "lerax_like/Acrobot-v1": [([3.1, -3.1, 12.5, 28.0], 2), ([-3.13, 3.13, -20.0, -40.0], 0)],
    "lerax_like/MountainCar-v0": [([-1.19, -0.069], 0), ([0.59, 0.069], 2), ([0.49, 0.0], 2)],
    "lerax_like/MountainCarContinuous-v0": [
        ([-1.19, -0.069], np.array([-1.0])),
        ([0.59, 0.069], np.array([3.0])),
        ([0.449, 0.0005], np.array([1.0])),
    ],
}


# Events that the episodes above must contain, detected on Gymnasium's trajectory:
# (previous state, state, terminated, truncated) -> bool.
EVENTS = {
    "lerax_like/CartPole-v1": {
        "terminated": lambda s0, s1, te, tr: te,
        "truncated": lambda s0, s1, te, tr: tr,
    },
    "lerax_like/Pendulum-v1": {
        "speed clipped": lambda s0, s1, te, tr: abs(s1[1]) == 8.0,
        "truncated": lambda s0, s1, te, tr: tr,
    },
    "lerax_like/Acrobot-v1": {
        "angle wrapped": lambda s0, s1, te, tr: np.any(np.abs(s1[:2] - s0[:2]) > np.pi),
        "terminated": lambda s0, s1, te, tr: te,
        "truncated": lambda s0, s1, te, tr: tr,
    },
    "lerax_like/MountainCar-v0": {
        "left wall": lambda s0, s1, te, tr: s1[0] == -1.2 and s1[1] == 0.0,
        "goal": lambda s0, s1, te, tr: te,
    },
    "lerax_like/MountainCarContinuous-v0": {
        "left wall": lambda s0, s1, te, tr: s1[0] == np.float32(-1.2) and s1[1] == 0.0,
        "goal": lambda s0, s1, te, tr: te,
    },
}


def _compare_step(ours, reference, env_id, context):
    observation, reward, terminated, truncated, info = ours
    ref_observation, ref_reward, ref_terminated, ref_truncated, _ = reference
    rtol = STATE_RTOL[env_id]
    assert observation.dtype == np.float32 and observation.shape == ref_observation.shape, context
    # float32 observations of float64 states that agree to `rtol`: one float32 rounding apart.
    np.testing.assert_allclose(observation, ref_observation, rtol=max(rtol, 2**-23), atol=1e-12, err_msg=context)
    assert type(reward) is float, context
    np.testing.assert_allclose(reward, float(ref_reward), rtol=rtol, atol=1e-12, err_msg=context)
    assert type(terminated) is bool and terminated == ref_terminated, context
    assert type(truncated) is bool and truncated == ref_truncated, context
    assert info["solver_ok"] is True and info["solver_steps"] == 1, context


def _assert_state_close(state, ref_state, rtol, context):
    state = np.asarray(state)
    ref_state = np.asarray(ref_state, dtype=np.float64)
    assert state.dtype == np.float64 and state.shape == ref_state.shape, context
    scale = np.max(np.abs(ref_state))
    assert np.max(np.abs(state - ref_state)) <= rtol * scale, (context, state, ref_state)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_registration_matches_gymnasium(env_id):
    registered(env_id)
    ours, reference = gymnasium.spec(env_id), gymnasium.spec(reference_id(env_id))
    assert ours.max_episode_steps == reference.max_episode_steps
    assert ours.reward_threshold == reference.reward_threshold
    env, ref_env = gymnasium.make(env_id), gymnasium.make(reference_id(env_id))
    assert env.action_space == ref_env.action_space
    assert env.observation_space == ref_env.observation_space


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_reset_draws_as_gymnasium(env_id):
    env = gymnasium.make(registered(env_id))
    ref_env = gymnasium.make(reference_id(env_id))
    options = {
        "lerax_like/Pendulum-v1": {"x_init": 0.3, "y_init": 0.2},
    }.get(env_id, {"low": -0.2, "high": -0.1})
    for seed, reset_options in [(0, None), (1, None), (42, None), (2**31 + 7, None), (5, options)]:
        observation, info = env.reset(seed=seed, options=reset_options)
        ref_observation, _ = ref_env.reset(seed=seed, options=reset_options)
        assert observation.dtype == np.float32 and info == {}
        np.testing.assert_array_equal(observation, ref_observation)
        np.testing.assert_array_equal(env.unwrapped.state, np.asarray(ref_env.unwrapped.state, dtype=np.float64))
        # An unseeded reset continues the same generator.
        np.testing.assert_array_equal(env.reset()[0], ref_env.reset()[0])


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_whole_episodes_match_gymnasium(env_id):
    env = gymnasium.make(registered(env_id))
    ref_env = gymnasium.make(reference_id(env_id))
    rtol = STATE_RTOL[env_id]
    seen = dict.fromkeys(EVENTS[env_id], 0)
    for seed, options, policy in EPISODES[env_id]:
        rng = np.random.default_rng(seed)
        env.reset(seed=seed, options=options)
        ref_env.reset(seed=seed, options=options)
        for step in range(1000):
            ref_state = np.asarray(ref_env.unwrapped.state, dtype=np.float64)
            env.unwrapped.state = ref_state
            action = policy(step, ref_state, rng)
            ours = env.step(action)
            reference = ref_env.step(action)
            context = f"{env_id} seed {seed} step {step}"
            _compare_step(ours, reference, env_id, context)
            _assert_state_close(env.unwrapped.state, ref_env.unwrapped.state, rtol, context)
            for name, happened in EVENTS[env_id].items():
                seen[name] += bool(happened(ref_state, np.asarray(ref_env.unwrapped.state), *reference[2:4]))
            if reference[2] or reference[3]:
                break
    assert all(seen.values()), seen


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_edge_states_match_gymnasium(env_id):
    env = gymnasium.make(registered(env_id)).unwrapped
    ref_env = gymnasium.make(reference_id(env_id)).unwrapped
    for state, action in EDGE_CASES[env_id]:
        env.reset(seed=0)
        ref_env.reset(seed=0)  # Gymnasium's CartPole pays 0 for steps after a termination
        env.state = np.array(state)
        ref_env.state = np.array(state, dtype=np.float64)
        context = f"{env_id} from {state}"
        _compare_step(env.step(action), ref_env.step(action), env_id, context)
        _assert_state_close(env.state, ref_env.state, STATE_RTOL[env_id], context)


def test_state_is_float64_and_writable_in_place():
    env = gymnasium.make("lerax_like/CartPole-v1").unwrapped
    ref_env = gymnasium.make("CartPole-v1").unwrapped
    env.reset(seed=3)
    ref_env.reset(seed=3)
    assert env.state.dtype == np.float64 and env.state.shape == (4,)
    env.state[2] = 0.1  # in place, as people do for model-predictive control
    ref_env.state[2] = 0.1
    _compare_step(env.step(1), ref_env.step(1), "lerax_like/CartPole-v1", "in-place write")
    _assert_state_close(env.state, ref_env.state, 1e-12, "in-place write")


def test_float64_is_scoped_to_the_wrapper():
    # The wrapper must not rely on (or switch on) the global x64 flag.
    jax.config.update("jax_enable_x64", False)
    try:
        env = gymnasium.make("lerax_like/CartPole-v1").unwrapped
        ref_env = gymnasium.make("CartPole-v1").unwrapped
        env.reset(seed=0)
        ref_env.reset(seed=0)
        for step in range(20):
            _compare_step(env.step(step % 2), ref_env.step(step % 2), "lerax_like/CartPole-v1", "x64 off")
            _assert_state_close(env.state, ref_env.state, 1e-12, f"x64 off, step {step}")
        assert env.scene.dynamics.gravity.dtype == np.float64
        assert not jax.config.jax_enable_x64
    finally:
        jax.config.update("jax_enable_x64", True)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_invalid_actions_are_refused(env_id):
    env = gymnasium.make(registered(env_id)).unwrapped
    ref_env = gymnasium.make(reference_id(env_id)).unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    ref_env.reset(seed=0)
    if isinstance(env.action_space, gymnasium.spaces.Discrete):
        for action in (env.action_space.n, -1, 0.5, "left"):
            if env_id != "lerax_like/Acrobot-v1":  # Gymnasium's Acrobot does not check
                with pytest.raises(AssertionError):
                    ref_env.step(action)
            # A ValueError, not Gymnasium's assert: it holds under `python -O`.
            with pytest.raises(ValueError, match=r"action .* is not in Discrete"):
                env.step(action)
    else:
        # Gymnasium clips a continuous action; it must still be one number.
        for action in (np.zeros(2), np.zeros(0)):
            with pytest.raises(ValueError, match="shape"):
                env.step(action)


def test_solver_and_parameters_pass_through_make():
    ref_env = gymnasium.make("CartPole-v1").unwrapped
    ref_env.reset(seed=0)
    state = np.array([0.1, -0.5, 0.15, 1.0])
    euler = gymnasium.make("lerax_like/CartPole-v1").unwrapped
    rk4 = gymnasium.make("lerax_like/CartPole-v1", solver="rk4").unwrapped
    rk4_object = gymnasium.make("lerax_like/CartPole-v1", solver=lerax_like.RK4()).unwrapped
    heavy = gymnasium.make("lerax_like/CartPole-v1", gravity=12.0, pole_mass=0.3).unwrapped
    assert isinstance(rk4.scene.integrator.solver, lerax_like.RK4)
    assert float(heavy.scene.dynamics.gravity) == 12.0 and float(heavy.scene.dynamics.pole_mass) == 0.3
    ref_env.state = state.copy()
    ref_env.step(1)
    results = {}
    for name, env in [("euler", euler), ("rk4", rk4), ("rk4_object", rk4_object), ("heavy", heavy)]:
        env.reset(seed=0)
        env.state = state
        env.step(1)
        results[name] = env.state
    _assert_state_close(results["euler"], ref_env.state, 1e-12, "euler")
    np.testing.assert_array_equal(results["rk4"], results["rk4_object"])
    # RK4 differs from Euler by O(dt^2) in one step; a heavier, stronger-pulled pole too.
    assert 1e-8 < np.max(np.abs(results["rk4"] - results["euler"])) < 1e-2
    assert np.max(np.abs(results["heavy"] - results["euler"])) > 1e-4


def _checker_warnings(env) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    return sorted({str(warning.message) for warning in caught})


@pytest.mark.parametrize("solver", [None, "rk4", "tsit5"])
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasium_check_env(env_id, solver):
    kwargs = {} if solver is None else {"solver": solver}
    ours = _checker_warnings(gymnasium.make(registered(env_id), **kwargs))
    reference = _checker_warnings(gymnasium.make(reference_id(env_id)))
    assert set(ours) <= set(reference), set(ours) - set(reference)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_render_draws_gymnasiums_frame(env_id):
    env = gymnasium.make(registered(env_id), render_mode="rgb_array")
    ref_env = gymnasium.make(reference_id(env_id), render_mode="rgb_array")
    env.reset(seed=4)
    ref_env.reset(seed=4)
    frame, ref_frame = env.render(), ref_env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    np.testing.assert_array_equal(frame, ref_frame)
    action = EDGE_CASES[env_id][0][1]
    env.step(action)
    ref_env.step(action)
    np.testing.assert_array_equal(env.render(), ref_env.render())
    env.close()
    ref_env.close()


def test_render_without_pygame_hints_the_extra(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "pygame", None)  # makes `import pygame` fail
    env = gymnasium.make("lerax_like/CartPole-v1", render_mode="rgb_array")
    env.reset(seed=0)
    with pytest.raises(gymnasium.error.DependencyNotInstalled, match=r"lerax_like\[render\]"):
        env.render()


# ---------------------------------------------------------------- vector env


def _vector_pair(num_envs, max_episode_steps):
    ours = gymnasium.make_vec(
        "lerax_like/CartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point",
        max_episode_steps=max_episode_steps,
    )
    reference = gymnasium.make_vec(
        "CartPole-v1", num_envs=num_envs, vectorization_mode="vector_entry_point",
        max_episode_steps=max_episode_steps,
    )
    return ours, reference


def test_vector_env_matches_gymnasiums_vector_cartpole():
    num_envs = 6
    ours, reference = _vector_pair(num_envs, max_episode_steps=40)
    assert isinstance(ours, gymnasium.vector.VectorEnv)
    assert ours.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    assert ours.single_action_space == reference.single_action_space
    assert ours.action_space == reference.action_space
    assert ours.observation_space == reference.observation_space
    rng = np.random.default_rng(0)
    ends = restarts = 0
    for seed, options in [(7, None), (8, {"low": -0.15, "high": 0.15})]:
        observation, _ = ours.reset(seed=seed, options=options)
        ref_observation, _ = reference.reset(seed=seed, options=options)
        np.testing.assert_array_equal(observation, ref_observation)
        previous_done = np.zeros(num_envs, dtype=bool)
        for step in range(150):
            # Mostly balancing, with random pushes: falls and time limits both occur.
            state = reference.unwrapped.state
            balance = (state[2] + 0.5 * state[3] > 0).astype(np.int64)
            actions = np.where(rng.random(num_envs) < 0.3, rng.integers(0, 2, num_envs), balance)
            observation, reward, terminated, truncated, info = ours.step(actions)
            ref_observation, ref_reward, ref_terminated, ref_truncated, _ = reference.step(actions)
            context = f"seed {seed} step {step}"
            np.testing.assert_allclose(observation, ref_observation, rtol=2**-23, atol=1e-12, err_msg=context)
            np.testing.assert_array_equal(reward, ref_reward, err_msg=context)
            np.testing.assert_array_equal(terminated, ref_terminated, err_msg=context)
            np.testing.assert_array_equal(truncated, ref_truncated, err_msg=context)
            assert observation.dtype == np.float32 and terminated.dtype == truncated.dtype == np.bool_
            _assert_state_close(ours.unwrapped.state, reference.unwrapped.state, 1e-12, context)
            # Next-step autoreset, stated directly: the step after an end restarts the env.
            assert np.all(reward[previous_done] == 0.0), context
            assert not np.any(terminated[previous_done] | truncated[previous_done]), context
            # A restarted env has only its reset's (empty) info, as in Gymnasium's SyncVectorEnv.
            np.testing.assert_array_equal(info.get("_solver_ok", np.zeros(num_envs, dtype=bool)), ~previous_done)
            assert "solver_ok" not in info or np.all(info["solver_ok"])
            ends += int(np.sum(terminated | truncated))
            restarts += int(np.sum(previous_done))
            previous_done = terminated | truncated
    assert ends > 10 and restarts > 10  # both kinds of end and their restarts were exercised
    ours.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_vector_env_steps_as_gymnasium_single_envs(env_id):
    num_envs = 3
    vector = gymnasium.make_vec(registered(env_id), num_envs=num_envs, vectorization_mode="vector_entry_point",
                                max_episode_steps=4, render_mode="rgb_array")
    references = [gymnasium.make(reference_id(env_id)).unwrapped for _ in range(num_envs)]
    vector.reset(seed=0)
    for index, reference in enumerate(references):
        reference.reset(seed=index)
    rtol = STATE_RTOL[env_id]
    for step in range(4):
        states = np.stack([np.asarray(reference.state, dtype=np.float64) for reference in references], axis=1)
        vector.unwrapped.state = states
        actions = [EDGE_CASES[env_id][step % len(EDGE_CASES[env_id])][1] for _ in references]
        observation, reward, terminated, truncated, _ = vector.step(np.stack(actions))
        for index, (reference, action) in enumerate(zip(references, actions)):
            ref_observation, ref_reward, ref_terminated, _, _ = reference.step(action)
            context = f"{env_id} env {index} step {step}"
            np.testing.assert_allclose(observation[index], ref_observation, rtol=max(rtol, 2**-23), atol=1e-12, err_msg=context)
            np.testing.assert_allclose(reward[index], ref_reward, rtol=rtol, atol=1e-12, err_msg=context)
            assert terminated[index] == ref_terminated, context
            _assert_state_close(vector.unwrapped.state[:, index], reference.state, rtol, context)
        assert np.all(truncated == (step == 3))
    # All envs hit the time limit at step 4: the next step restarts them all.
    previous = vector.unwrapped.state
    observation, reward, terminated, truncated, _ = vector.step(np.stack(actions))
    assert np.all(reward == 0.0) and not np.any(terminated | truncated)
    assert not np.allclose(vector.unwrapped.state, previous)
    frames = vector.render()
    assert len(frames) == num_envs and all(frame.dtype == np.uint8 and frame.shape[2] == 3 for frame in frames)
    vector.close()


def test_vector_env_refuses_invalid_actions():
    ours, reference = _vector_pair(3, 4)
    ours.reset(seed=0)
    reference.reset(seed=0)
    for actions in (np.array([0, 1, 2]), np.array([0, 1])):
        with pytest.raises(AssertionError):
            reference.step(actions)
        with pytest.raises(ValueError, match=r"actions"):
            ours.step(actions)


@pytest.mark.slow  # 3.3 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_a_stochastic_scene_gets_seeded_keys_through_the_layer(noisy_cartpole):
    # Every built-in scene is deterministic; the layer's key path is for scenes like this.
    def episode(env):
        env.unwrapped.scene = noisy_cartpole()
        observation, _ = env.reset(seed=5)
        observations = [observation]
        for _ in range(5):
            observations.append(env.step(1)[0])
        return np.array(observations), env.unwrapped.state

    first, state = episode(gymnasium.make("lerax_like/CartPole-v1"))
    second, _ = episode(gymnasium.make("lerax_like/CartPole-v1"))
    np.testing.assert_array_equal(first, second)  # the seed fixes the noise
    noise = first[-1] - state.astype(np.float32)
    assert 1e-5 < np.max(np.abs(noise)) < 1e-2
    assert len({tuple(row) for row in np.diff(first, axis=0)}) == 5  # fresh noise each step

    vector = gymnasium.make_vec("lerax_like/CartPole-v1", num_envs=3, vectorization_mode="vector_entry_point")
    vector.scene = noisy_cartpole()
    observations, _ = vector.reset(seed=5)
    observations = vector.step(np.ones(3, dtype=np.int64))[0]
    noise = observations - vector.state.T.astype(np.float32)
    assert 1e-5 < np.max(np.abs(noise)) < 1e-2
    assert len({tuple(row) for row in noise}) == 3  # each env its own noise
