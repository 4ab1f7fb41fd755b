"""Gymnasium's own checks of a registered env, run over every `lerax_like/` id.

Ported from Gymnasium's test suite (`tests/envs/test_envs.py`, `tests/envs/registration/
test_env_spec.py`): determinism of rollouts, render modes, pickling, the spec's JSON round
trip, `pprint` and equality, `make_vec` in each mode. Besides: Gymnasium's constructor
keywords and attributes, compared with Gymnasium's env given the same keyword or attribute
(the reference), and subprocess vector envs.
"""

import os
import pickle
import subprocess
import sys
import textwrap

import cloudpickle
import gymnasium
import numpy as np
import pytest
from gymnasium.envs.registration import EnvSpec
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.utils.env_match import check_environments_match

from lerax_like.gym import SPECS


os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # the "human" mode opens a window

# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)


def reference_id(env_id: str) -> str:
    return SPECS[env_id].name


# -- tests/envs/test_envs.py ---------------------------------------------------------------


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_determinism_rollout(env_id):
    env_1 = gymnasium.make(env_id, disable_env_checker=True)
    env_2 = gymnasium.make(env_id, disable_env_checker=True)
    observation_1, info_1 = env_1.reset(seed=0)
    observation_2, info_2 = env_2.reset(seed=0)
    assert data_equivalence(observation_1, observation_2) and data_equivalence(info_1, info_2)
    env_1.action_space.seed(0)
    for _ in range(50):
        action = env_1.action_space.sample()
        outcome_1, outcome_2 = env_1.step(action), env_2.step(action)
        assert data_equivalence(outcome_1, outcome_2)
        assert env_1.observation_space.contains(outcome_1[0])
        if outcome_1[2] or outcome_1[3]:
            env_1.reset(seed=0)
            env_2.reset(seed=0)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_environments_match_with_gymnasiums_checker(env_id):
    # Gymnasium's `check_environments_match`, renders included.
    check_environments_match(
        gymnasium.make(env_id, render_mode="rgb_array"), gymnasium.make(env_id, render_mode="rgb_array"), 30, seed=3
    )


def check_rendered(frame, mode: str) -> None:
    if mode == "rgb_array_list":
        assert isinstance(frame, list) and frame
        for each in frame:
            check_rendered(each, "rgb_array")
    elif mode == "rgb_array":
        assert isinstance(frame, np.ndarray) and frame.ndim == 3 and frame.shape[2] == 3
        assert frame.dtype == np.uint8
    else:
        assert frame is None  # "human" draws to the window


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_render_modes(env_id):
    reference = gymnasium.make(reference_id(env_id))
    env = gymnasium.make(env_id)
    assert env.metadata["render_modes"] == reference.metadata["render_modes"]
    assert env.metadata["render_fps"] == reference.metadata["render_fps"]
    # Every mode of Gymnasium's env, and the `_list` mode `gymnasium.make` adds.
    for mode in [*reference.metadata["render_modes"], "rgb_array_list"]:
        new_env = gymnasium.make(env_id, render_mode=mode)
        assert new_env.render_mode == mode
        new_env.reset(seed=0)
        check_rendered(new_env.render(), mode)
        new_env.step(new_env.action_space.sample())
        check_rendered(new_env.render(), mode)
        new_env.close()


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_rgb_array_list_collects_the_frames_of_rgb_array(env_id):
    listed = gymnasium.make(env_id, render_mode="rgb_array_list")
    single = gymnasium.make(env_id, render_mode="rgb_array")
    assert isinstance(listed, gymnasium.wrappers.RenderCollection)
    frames = []
    for env in (listed, single):
        env.reset(seed=1)
        env.action_space.seed(1)
    frames.append(single.render())
    for _ in range(3):
        action = listed.action_space.sample()
        listed.step(action)
        single.step(action)
        frames.append(single.render())
    collected = listed.render()
    assert len(collected) == len(frames)
    for a, b in zip(collected, frames, strict=True):
        np.testing.assert_array_equal(a, b)


# -- pickling (test_envs.py: test_pickle_env; test_env_spec.py: test_pickling_env_stack) ----


def _continue(env, actions):
    """The outcomes of `actions` from the env's current state, then of an unseeded reset."""
    outcomes = [env.step(action) for action in actions]
    outcomes.append(env.reset())  # draws from np_random: its state must have been copied
    return outcomes


def _actions(env, n, seed):
    env.action_space.seed(seed)
    return [env.action_space.sample() for _ in range(n)]


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_pickle_env_before_and_after_reset(env_id):
    env = gymnasium.make(env_id)
    fresh = pickle.loads(pickle.dumps(env))
    assert data_equivalence(env.reset(seed=7), fresh.reset(seed=7))
    actions = _actions(env, 60, seed=1)
    for action in actions[:20]:
        env.step(action)
        fresh.step(action)
    copy = pickle.loads(pickle.dumps(env))
    assert type(copy.unwrapped) is type(env.unwrapped)
    np.testing.assert_array_equal(copy.unwrapped.state, env.unwrapped.state)
    original = _continue(env, actions[20:])
    assert data_equivalence(original, _continue(copy, actions[20:]))
    assert data_equivalence(original, _continue(fresh, actions[20:]))


def test_pickling_env_stack():
    # FlattenObservation holds a lambda: Gymnasium pickles this stack with dill; cloudpickle
    # (a dependency of Gymnasium, what its AsyncVectorEnv ships envs with) does as well.
    env = gymnasium.make("lerax_like/Pendulum-v1", render_mode="rgb_array")
    env = gymnasium.wrappers.FlattenObservation(env)
    env = gymnasium.wrappers.TimeAwareObservation(env)
    env = gymnasium.wrappers.NormalizeReward(env, gamma=0.8)
    copy = pickle.loads(cloudpickle.dumps(env))
    assert data_equivalence(env.reset(seed=123), copy.reset(seed=123))
    for action in _actions(env, 10, seed=2):
        assert data_equivalence(env.step(action), copy.step(action))
    np.testing.assert_array_equal(env.render(), copy.render())


def test_pickle_rgb_array_list_env_keeps_its_frames():
    env = gymnasium.make("lerax_like/CartPole-v1", render_mode="rgb_array_list")
    env.reset(seed=0)
    env.step(1)
    copy = pickle.loads(pickle.dumps(env))
    for a, b in zip(env.render(), copy.render(), strict=True):
        np.testing.assert_array_equal(a, b)


def test_pickle_keeps_written_attributes_and_keywords():
    env = gymnasium.make("lerax_like/CartPole-v1", solver="rk4", sutton_barto_reward=True)
    env.unwrapped.gravity = 3.0
    copy = pickle.loads(pickle.dumps(env))
    assert copy.get_wrapper_attr("gravity") == 3.0
    assert copy.unwrapped.scene.sutton_barto_reward
    assert type(copy.unwrapped.scene.integrator.solver) is type(env.unwrapped.scene.integrator.solver)
    assert data_equivalence(env.reset(seed=0), copy.reset(seed=0))
    for action in [1] * 40:
        assert data_equivalence(env.step(action), copy.step(action))


def test_pickle_carries_a_stochastic_scenes_key(noisy_cartpole):
    env = gymnasium.make("lerax_like/CartPole-v1")
    env.unwrapped.scene = noisy_cartpole()
    env.reset(seed=4)
    env.step(1)
    copy = pickle.loads(pickle.dumps(env))
    steps = [env.step(action) for action in (0, 1, 0)]
    assert data_equivalence(steps, [copy.step(action) for action in (0, 1, 0)])
    assert not data_equivalence(steps[0][0], steps[1][0])


@pytest.mark.parametrize("env_id", ["lerax_like/CartPole-v1", "lerax_like/MountainCarContinuous-v0"])
def test_pickle_vector_env(env_id):
    # Two envs, as test_make_vec: the same compiled programs serve both tests.
    vector = gymnasium.make_vec(env_id, 2, vectorization_mode="vector_entry_point", max_episode_steps=15)
    fresh = pickle.loads(pickle.dumps(vector))
    assert data_equivalence(vector.reset(seed=3), fresh.reset(seed=3))
    vector.action_space.seed(3)
    actions = [vector.action_space.sample() for _ in range(40)]  # autoresets after 15 steps
    for action in actions[:17]:
        vector.step(action)
        fresh.step(action)
    copy = pickle.loads(pickle.dumps(vector))
    for action in actions[17:]:
        outcome = vector.step(action)
        assert data_equivalence(outcome, copy.step(action))
        assert data_equivalence(outcome, fresh.step(action))
    assert data_equivalence(vector.reset(), copy.reset())


_SUBPROCESS = textwrap.dedent(
    """
    import pickle, sys
    env, vector, actions, vector_actions = pickle.loads(sys.stdin.buffer.read())
    import jax
    assert not jax.config.jax_enable_x64  # loaded in a process without float64 on
    outcomes = [env.step(a) for a in actions], [vector.step(a) for a in vector_actions]
    sys.stdout.buffer.write(pickle.dumps((outcomes, env.unwrapped.state.dtype.name)))
    """
)


@pytest.mark.slow
def test_pickled_envs_continue_exactly_in_a_fresh_process():
    # In this process float64 is on (conftest); a worker process need not have it on.
    env = gymnasium.make("lerax_like/Pendulum-v1")
    vector = gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="vector_entry_point")
    env.reset(seed=1)
    vector.reset(seed=1)
    actions = _actions(env, 20, seed=0)
    vector_actions = [np.array([1, 0])] * 20
    payload = pickle.dumps((env, vector, actions, vector_actions))
    result = subprocess.run(
        [sys.executable, "-c", _SUBPROCESS], input=payload, capture_output=True, check=False,
        env={**os.environ, "JAX_ENABLE_X64": "0", "JAX_PLATFORMS": "cpu"},
    )
    assert result.returncode == 0, result.stderr.decode()[-2000:]
    (outcomes, vector_outcomes), dtype = pickle.loads(result.stdout)
    assert dtype == "float64"
    assert data_equivalence(outcomes, [env.step(a) for a in actions])
    assert data_equivalence(vector_outcomes, [vector.step(a) for a in vector_actions])


# -- tests/envs/registration/test_env_spec.py ----------------------------------------------


def _specs_of(env_id):
    return {
        "registered": gymnasium.spec(env_id),
        "unwrapped": gymnasium.make(env_id).unwrapped.spec,
        "made": gymnasium.make(env_id).spec,
        "wrapped": gymnasium.wrappers.NormalizeReward(gymnasium.make(env_id)).spec,
    }


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_spec_to_from_json(env_id):
    for spec in _specs_of(env_id).values():
        assert EnvSpec.from_json(spec.to_json()) == spec


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_made_spec_equals_registered_spec(env_id):
    assert gymnasium.make(env_id).spec == gymnasium.spec(env_id)
    registered = gymnasium.spec(env_id)
    assert isinstance(registered.entry_point, str) and isinstance(registered.vector_entry_point, str)
    # The entry point names what `make` calls: a creator of the env class `make` builds,
    # whose metadata (read by `make` before it builds) is the env's.
    module, name = registered.entry_point.split(":")
    creator, made = getattr(sys.modules[module], name), gymnasium.make(env_id).unwrapped
    assert type(made) is creator.env_class and creator.metadata == made.metadata


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_full_integration(env_id):
    env = gymnasium.make(env_id, render_mode="rgb_array", solver="rk4")
    env = gymnasium.wrappers.TimeAwareObservation(env)
    env = gymnasium.wrappers.NormalizeReward(env, gamma=0.8)
    spec = env.spec
    assert len(spec.additional_wrappers) == 2
    recreated_spec = EnvSpec.from_json(spec.to_json())
    assert recreated_spec == spec
    recreated = gymnasium.make(recreated_spec)
    assert recreated.render_mode == "rgb_array"
    assert isinstance(recreated, gymnasium.wrappers.NormalizeReward) and recreated.gamma == 0.8
    assert type(recreated.unwrapped) is type(env.unwrapped)
    assert type(recreated.unwrapped.scene.integrator.solver) is type(env.unwrapped.scene.integrator.solver)
    assert data_equivalence(env.reset(seed=42), recreated.reset(seed=42))
    action = env.action_space.sample()
    assert data_equivalence(env.step(action), recreated.step(action))
    assert spec.pprint(disable_print=True) == recreated_spec.pprint(disable_print=True)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_spec_pprint_as_gymnasiums(env_id):
    # Our spec prints as Gymnasium's spec of the same env, but for the id and entry points.
    def printed(name, **options):
        env = gymnasium.wrappers.TimeAwareObservation(gymnasium.make(name))
        return env.spec.pprint(disable_print=True, **options)

    reference = reference_id(env_id)
    ours_entry, reference_entry = gymnasium.spec(env_id).entry_point, gymnasium.spec(reference).entry_point
    for options in ({}, {"print_all": True}, {"include_entry_points": True}):
        expected = printed(reference, **options).replace(f"id={reference}", f"id={env_id}")
        assert printed(env_id, **options) == expected.replace(f"entry_point={reference_entry}", f"entry_point={ours_entry}")


# -- make_vec (tests/envs/registration/test_make_vec.py) -------------------------------------


@pytest.mark.parametrize("env_id", ALL_IDS)
@pytest.mark.parametrize("mode", ["sync", "vector_entry_point"])
def test_make_vec(env_id, mode):
    vector = gymnasium.make_vec(env_id, 2, vectorization_mode=mode)
    assert vector.num_envs == 2
    assert vector.spec.kwargs["vectorization_mode"] == mode
    assert vector.single_action_space == gymnasium.make(env_id).action_space
    assert vector.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    observation, _ = vector.reset(seed=0)
    assert vector.observation_space.contains(observation)
    observation, reward, terminated, truncated, _ = vector.step(vector.action_space.sample())
    assert vector.observation_space.contains(observation)
    assert reward.shape == terminated.shape == truncated.shape == (2,)
    vector.close()


@pytest.mark.slow
def test_make_vec_async_forkserver_steps_as_sync():
    # Subprocess workers by forkserver (fork warns that JAX's threads may deadlock). The
    # sync vector env seeds its envs as the async one does: the same numbers.
    context = {"context": "forkserver"}
    envs = gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="async", vector_kwargs=context)
    reference = gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="sync")
    try:
        assert data_equivalence(envs.reset(seed=0), reference.reset(seed=0))
        for step in range(30):
            actions = np.array([step % 2, 1])
            assert data_equivalence(envs.step(actions), reference.step(actions))
    finally:
        envs.close()


# -- Gymnasium's constructor keywords -------------------------------------------------------


def _episode(env, actions, seed):
    outcomes = [env.reset(seed=seed)]
    for action in actions:
        outcomes.append(env.step(action))
        if outcomes[-1][2] or outcomes[-1][3]:
            break
    return outcomes


def _assert_episodes_close(ours, reference, rtol):
    assert len(ours) == len(reference)
    np.testing.assert_allclose(ours[0][0], reference[0][0], rtol=rtol, atol=1e-7)
    for a, b in zip(ours[1:], reference[1:], strict=True):
        np.testing.assert_allclose(a[0], b[0], rtol=rtol, atol=1e-7)
        assert a[1] == pytest.approx(b[1], rel=rtol, abs=1e-9)
        assert (a[2], a[3]) == (b[2], b[3])


def test_sutton_barto_reward_as_gymnasium():
    ours = gymnasium.make("lerax_like/CartPole-v1", sutton_barto_reward=True)
    reference = gymnasium.make("CartPole-v1", sutton_barto_reward=True)
    actions = [1] * 100
    episode = _episode(ours, actions, seed=0)
    _assert_episodes_close(episode, _episode(reference, actions, seed=0), rtol=1e-6)
    rewards = [outcome[1] for outcome in episode[1:]]
    assert rewards[-1] == -1.0 and set(rewards[:-1]) == {0.0} and episode[-1][2]
    assert ours.unwrapped.scene.worst_reward == -1.0


def test_pendulum_g_as_gymnasium():
    ours = gymnasium.make("lerax_like/Pendulum-v1", g=3.0)
    reference = gymnasium.make("Pendulum-v1", g=3.0)
    actions = [np.array([0.3], dtype=np.float32)] * 50
    _assert_episodes_close(_episode(ours, actions, seed=2), _episode(reference, actions, seed=2), rtol=1e-6)
    assert ours.get_wrapper_attr("g") == 3.0


# -- Gymnasium's attributes, readable and writable ------------------------------------------

STATE_TOLERANCE = {  # (rtol, atol) of the state
    "lerax_like/CartPole-v1": (1e-10, 1e-12),
    # Gymnasium's Pendulum computes its torque term `3 / (m l^2) * u` in float32 (NumPy
    # keeps a Python float times the float32 action in float32); ours in float64.
    "lerax_like/Pendulum-v1": (1e-6, 1e-12),
    "lerax_like/Acrobot-v1": (1e-10, 1e-12),
    "lerax_like/MountainCar-v0": (1e-10, 1e-12),
    # Gymnasium's continuous mountain car keeps its state in float32: a velocity of order
    # 1e-3 carries absolute rounding errors of a few 1e-9 after tens of steps.
    "lerax_like/MountainCarContinuous-v0": (1e-5, 1e-7),
}


def _attributes(env_id):
    """Gymnasium's attributes that the spec maps and Gymnasium's env has (its continuous
    mountain car has no `gravity`: the constant is written into its step)."""
    reference = gymnasium.make(reference_id(env_id)).unwrapped
    names = list(dict.fromkeys(name for name, _ in SPECS[env_id].declared.attributes))
    present = [name for name in names if hasattr(reference, name)]
    assert set(names) - set(present) <= {"gravity"}, set(names) - set(present)
    return present


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasiums_attributes_read_as_gymnasiums_defaults(env_id):
    env = gymnasium.make(env_id)
    reference = gymnasium.make(reference_id(env_id))
    for name in _attributes(env_id):
        assert env.get_wrapper_attr(name) == pytest.approx(float(getattr(reference.unwrapped, name)), rel=1e-12), name


def _set_on_reference(reference, name, value):
    setattr(reference, name, value)
    if isinstance(reference, gymnasium.envs.classic_control.CartPoleEnv):
        # Gymnasium's CartPole caches these at construction; a write of a mass or the
        # length leaves them stale. Ours derives them, so the reference is made consistent.
        reference.total_mass = reference.masspole + reference.masscart
        reference.polemass_length = reference.masspole * reference.length


def _trajectory(env, actions, seed):
    env.reset(seed=seed)
    states, rewards, ends = [np.array(env.unwrapped.state, dtype=np.float64)], [], []
    for action in actions:
        _, reward, terminated, truncated, _ = env.step(action)
        states.append(np.array(env.unwrapped.state, dtype=np.float64))
        rewards.append(reward)
        ends.append(terminated)
        if terminated:
            break
    return np.array(states), np.array(rewards), np.array(ends)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_writing_gymnasiums_attributes_changes_the_physics_as_in_gymnasium(env_id):
    default = gymnasium.make(env_id, max_episode_steps=-1)
    default_run = _trajectory(default, _actions(default, 60, seed=0), seed=0)
    changed = []
    for name in _attributes(env_id):
        ours = gymnasium.make(env_id, max_episode_steps=-1)
        reference = gymnasium.make(reference_id(env_id), max_episode_steps=-1)
        compiled = ours.unwrapped.split.compiled.step
        value = ours.get_wrapper_attr(name)
        value = 0.7 * value if value != 0 else 0.01
        ours.set_wrapper_attr(name, value)
        _set_on_reference(reference.unwrapped, name, value)
        assert ours.get_wrapper_attr(name) == value
        assert ours.unwrapped.split.compiled.step is compiled  # a new parameter, not a new program
        actions = _actions(ours, 60, seed=0)
        run, reference_run = _trajectory(ours, actions, seed=0), _trajectory(reference, actions, seed=0)
        assert run[0].shape == reference_run[0].shape, name
        rtol, atol = STATE_TOLERANCE[env_id]
        np.testing.assert_allclose(run[0], reference_run[0], rtol=rtol, atol=atol, err_msg=name)
        np.testing.assert_allclose(run[1], reference_run[1], rtol=1e-6, err_msg=name)
        np.testing.assert_array_equal(run[2], reference_run[2], err_msg=name)
        if run[0].shape != default_run[0].shape or not np.allclose(run[0], default_run[0], rtol=1e-9):
            changed.append(name)
    # The writes are not no-ops: the physical ones change the trajectory.
    physical = {"gravity", "masscart", "masspole", "length", "force_mag", "tau", "g", "m", "l", "dt", "force", "power"}
    assert physical & set(_attributes(env_id)) <= set(changed)


def test_set_gravity_then_one_step_as_gymnasium():
    ours = gymnasium.make("lerax_like/CartPole-v1")
    reference = gymnasium.make("CartPole-v1")
    ours.set_wrapper_attr("gravity", 24.79)  # Jupiter
    reference.unwrapped.gravity = 24.79
    ours.reset(seed=0)
    reference.reset(seed=0)
    ours.unwrapped.state = reference.unwrapped.state = np.array([0.0, 0.0, 0.1, 0.0])
    ours.step(0)
    reference.step(0)
    np.testing.assert_allclose(ours.unwrapped.state, reference.unwrapped.state, rtol=1e-12)
    # Gymnasium's default gravity gives another state.
    earth = gymnasium.make("CartPole-v1")
    earth.reset(seed=0)
    earth.unwrapped.state = np.array([0.0, 0.0, 0.1, 0.0])
    earth.step(0)
    assert not np.allclose(ours.unwrapped.state, earth.unwrapped.state, rtol=1e-6)


@pytest.mark.slow  # 2.5 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_vector_env_has_gymnasiums_attributes():
    vector = gymnasium.make_vec("lerax_like/CartPole-v1", 2, vectorization_mode="vector_entry_point")
    assert vector.unwrapped.masspole == pytest.approx(0.1)
    vector.unwrapped.masspole = 0.5
    assert float(vector.unwrapped.scene.dynamics.pole_mass) == 0.5
