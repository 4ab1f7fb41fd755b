"""SB3's `VecEnv` contract in full over `lerax_like.sb3`, and every render mode of the vector env.

The reference is SB3's own `make_vec_env` over Gymnasium's env of the same name (a
`DummyVecEnv` of `Monitor`-wrapped `gymnasium.make` envs), run beside ours on the same
seeds and actions; for rendering, Gymnasium's `SyncVectorEnv` of Gymnasium's env.
"""

import os
import warnings

import gymnasium
import numpy as np
import pytest

import lerax_like  # noqa: F401  (registers the ids)
from lerax_like.gym import SPECS


pytest.importorskip("stable_baselines3")
from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env  # noqa: E402
from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor  # noqa: E402

from conftest import STATE_RTOL  # noqa: E402
from lerax_like.sb3 import CompiledVecEnv, make_vec_env  # noqa: E402


os.environ["SDL_VIDEODRIVER"] = "dummy"  # human rendering opens its window on no screen
# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)
NUM_ENVS = 3

# A physical attribute per id and a value within its range that changes the motion.
# Gymnasium's CartPole caches quantities derived from its masses at construction (stale
# after a write); a Gymnasium env built with the new mass has them recomputed, as here.
DERIVED = {
    "lerax_like/CartPole-v1": lambda env: {
        "total_mass": env.masspole + env.masscart, "polemass_length": env.masspole * env.length,
    },
}

CHANGED = {
    "lerax_like/CartPole-v1": ("masspole", 0.5),
    "lerax_like/Pendulum-v1": ("m", 2.5),
    "lerax_like/Acrobot-v1": ("LINK_MASS_2", 2.0),
    "lerax_like/MountainCar-v0": ("gravity", 0.004),
    "lerax_like/MountainCarContinuous-v0": ("power", 0.003),
}


def gymnasium_names(env_id: str) -> list[str]:
    """The attributes of the id's table that Gymnasium's env has (its continuous mountain
    car has no `gravity`: a literal in its step)."""
    reference = gymnasium.make(SPECS[env_id].name).unwrapped
    names = dict.fromkeys(name for name, _ in SPECS[env_id].declared.attributes)
    return [name for name in names if hasattr(reference, name)]


def pair(env_id: str, seed: int = 7, **kwargs):
    """Ours and SB3's `make_vec_env` over Gymnasium's env, same arguments."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return (
            make_vec_env(env_id, NUM_ENVS, seed=seed, **kwargs),
            sb3_make_vec_env(SPECS[env_id].name, NUM_ENVS, seed=seed, **kwargs),
        )


def actions(venv, count: int, seed: int) -> list[np.ndarray]:
    space = getattr(venv, "single_action_space", venv.action_space)  # Gymnasium's vector envs batch theirs
    space.seed(seed)
    # float64 continuous actions: Gymnasium's Pendulum computes its torque term in the
    # action's dtype (NumPy 2 promotion), so float32 ones would round it to float32.
    dtype = np.float64 if isinstance(space, gymnasium.spaces.Box) else np.int64
    return [np.array([space.sample() for _ in range(venv.num_envs)], dtype=dtype) for _ in range(count)]


def assert_states_close(ours, reference, rtol, context):
    for index, (state, ref_state) in enumerate(zip(ours, reference, strict=True)):
        ref_state = np.asarray(ref_state, dtype=np.float64)
        scale = np.max(np.abs(ref_state))
        assert np.max(np.abs(np.asarray(state) - ref_state)) <= rtol * scale, (context, index, state, ref_state)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_get_attr_reaches_gymnasiums_attributes_as_dummy_vec_env(env_id):
    ours, reference = pair(env_id)
    for name in [*gymnasium_names(env_id), "render_mode"]:
        assert ours.get_attr(name) == reference.get_attr(name), name
        assert ours.get_attr(name, indices=[2, 0]) == reference.get_attr(name, indices=[2, 0]), name
    # The state after a seeded reset: each env's own, Gymnasium's.
    ours.reset(), reference.reset()
    assert_states_close(ours.get_attr("state"), reference.get_attr("state"), STATE_RTOL[env_id], "state")


def test_get_attr_sees_the_keyword_applied():
    # The case: `goal_velocity` given to make_vec_env, then read back.
    ours, reference = pair("lerax_like/MountainCarContinuous-v0", env_kwargs={"goal_velocity": 0.25})
    assert ours.get_attr("goal_velocity") == reference.get_attr("goal_velocity") == [0.25] * NUM_ENVS


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_set_attr_with_indices_changes_the_physics_of_those_envs_only(env_id):
    name, value = CHANGED[env_id]
    ours, reference = pair(env_id)
    unchanged, _ = pair(env_id)
    default = ours.get_attr(name, indices=0)[0]
    assert value != default
    ours.set_attr(name, value, indices=[1])
    # DummyVecEnv's set_attr sets the attribute on the outer Monitor wrapper (Gymnasium 1.x
    # wrappers do not forward writes): the value reads back, the physics stays. The write
    # that reaches Gymnasium's env is set_wrapper_attr; it is the reference for the physics.
    _, wrapper_only = pair(env_id)
    wrapper_only.set_attr(name, value, indices=[1])
    assert wrapper_only.envs[1].unwrapped.get_wrapper_attr(name) == default
    assert reference.env_method("set_wrapper_attr", name, value, indices=[1]) == [True]
    assert reference.envs[1].unwrapped.get_wrapper_attr(name) == value
    for derived, each in DERIVED.get(env_id, lambda env: {})(reference.envs[1].unwrapped).items():
        reference.env_method("set_wrapper_attr", derived, each, indices=[1])
    assert ours.get_attr(name) == reference.get_attr(name) == wrapper_only.get_attr(name) == [default, value, default]

    ours.reset(), reference.reset(), unchanged.reset()
    rtol = STATE_RTOL[env_id]
    for step, action in enumerate(actions(ours, 5, seed=3)):
        ours.step(action), reference.step(action), unchanged.step(action)
        states = ours.get_attr("state")
        assert_states_close(states, reference.get_attr("state"), rtol, (env_id, step))
        plain = unchanged.get_attr("state")
        # The untouched envs step as in a batch of shared parameters (to rounding: the
        # per-env program is another XLA program, one ulp apart on Acrobot).
        assert_states_close([states[0], states[2]], [plain[0], plain[2]], 1e-14, (env_id, step))
    assert not np.array_equal(states[1], plain[1]), "the changed env moved as the unchanged one"


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_set_attr_of_every_env_and_refusals(env_id):
    name, value = CHANGED[env_id]
    ours, reference = pair(env_id)
    ours.set_attr(name, value)
    reference.set_attr(name, value)
    assert ours.get_attr(name) == reference.get_attr(name) == [value] * NUM_ENVS
    # A name the env does not have is kept per env, as DummyVecEnv keeps it on the wrapper.
    ours.set_attr("note", "x", indices=2)
    reference.set_attr("note", "x", indices=2)
    assert ours.get_attr("note", indices=2) == reference.get_attr("note", indices=2) == ["x"]
    with pytest.raises(AttributeError):
        ours.get_attr("note", indices=0)
    with pytest.raises(ValueError, match=name):
        ours.set_attr(name, -1.0, indices=[0])  # out of the parameter's range
    with pytest.raises(IndexError, match="indices"):
        ours.get_attr(name, indices=[NUM_ENVS])


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_method_as_dummy_vec_env(env_id):
    name, value = CHANGED[env_id]
    ours, reference = pair(env_id)
    for each in gymnasium_names(env_id):
        assert ours.env_method("get_wrapper_attr", each) == reference.env_method("get_wrapper_attr", each), each
    assert ours.env_method("has_wrapper_attr", name) == reference.env_method("has_wrapper_attr", name)
    set_ours = ours.env_method("set_wrapper_attr", name, value, indices=[0, 2])
    assert set_ours == reference.env_method("set_wrapper_attr", name, value, indices=[0, 2]) == [True, True]
    assert ours.get_attr(name) == reference.get_attr(name)
    # Each env's frame after the same seeded reset: Gymnasium's renderer on equal states.
    ours.reset(), reference.reset()
    for index, (frame, ref_frame) in enumerate(
        zip(ours.env_method("render", indices=[0, 1]), reference.env_method("render", indices=[0, 1]), strict=True)
    ):
        assert frame.shape == ref_frame.shape, index
        assert np.mean(frame != ref_frame) < 1e-3, index  # states equal to 1e-12: the same pixels
    with pytest.raises(AttributeError):
        ours.env_method("no_such_method")


def test_env_method_keyword_arguments_reach_the_method():
    ours, reference = pair("lerax_like/CartPole-v1")
    kwargs = {"name": "gravity", "value": 11.0, "force": False}
    assert ours.env_method("set_wrapper_attr", **kwargs) == reference.env_method("set_wrapper_attr", **kwargs)
    assert ours.get_attr("gravity") == reference.get_attr("gravity") == [11.0] * NUM_ENVS


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_env_is_wrapped_monitor_as_sb3_make_vec_env(env_id):
    ours, reference = pair(env_id)
    assert ours.env_is_wrapped(Monitor) == reference.env_is_wrapped(Monitor) == [True] * NUM_ENVS
    assert ours.env_is_wrapped(Monitor, indices=[1]) == reference.env_is_wrapped(Monitor, indices=[1]) == [True]
    # Unmonitored: the bare vector env and DummyVecEnv of bare envs.
    bare = CompiledVecEnv(env_id, NUM_ENVS)
    ref_bare = DummyVecEnv([lambda: gymnasium.make(SPECS[env_id].name)] * NUM_ENVS)
    assert bare.env_is_wrapped(Monitor) == ref_bare.env_is_wrapped(Monitor) == [False] * NUM_ENVS


def test_vec_monitor_over_a_monitored_env_warns_as_sb3_does():
    ours, reference = pair("lerax_like/CartPole-v1")
    with pytest.warns(UserWarning, match="already wrapped with a `Monitor`") as ref_record:
        VecMonitor(reference)
    with pytest.warns(UserWarning, match="already wrapped with a `Monitor`") as record:
        VecMonitor(ours)
    assert [str(w.message) for w in record] == [str(w.message) for w in ref_record]
    # Over the bare env, no warning, as over DummyVecEnv of bare envs.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        VecMonitor(CompiledVecEnv("lerax_like/CartPole-v1", NUM_ENVS))


def test_episode_statistics_once_per_episode():
    # One VecMonitor: an episode's statistics arrive once, in the step that ends it.
    venv = make_vec_env("lerax_like/CartPole-v1", 2, seed=0, env_kwargs={"max_episode_steps": 4})
    venv.reset()
    episodes = []
    for _ in range(8):
        _, _, done, infos = venv.step(np.array([0, 1]))
        episodes += [info["episode"] for info, ended in zip(infos, done) if ended]
        assert all(("episode" in info) == ended for info, ended in zip(infos, done))
    assert [episode["l"] for episode in episodes] == [4] * 4
    assert [episode["r"] for episode in episodes] == [4.0] * 4


def _display_pixels() -> np.ndarray:
    import pygame

    return np.transpose(pygame.surfarray.array3d(pygame.display.get_surface()), (1, 0, 2))


def _tiled(frames: list[np.ndarray]) -> np.ndarray:
    """The frames in a grid of ceil(sqrt(n)) columns, the empty cells black (as SB3's `tile_images`)."""
    from stable_baselines3.common.vec_env.base_vec_env import tile_images

    return tile_images(frames)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_render_mode_human_shows_every_env(env_id):
    pytest.importorskip("pygame")
    human, _ = pair(env_id, env_kwargs={"render_mode": "human"})
    frames, _ = pair(env_id, env_kwargs={"render_mode": "rgb_array"})
    assert human.render_mode == "human" and human.get_attr("render_mode") == ["human"] * NUM_ENVS
    human.reset(), frames.reset()
    for action in actions(human, 2, seed=1):
        human.step(action), frames.step(action)
        # The step itself showed the envs: the window holds their tiled frames.
        np.testing.assert_array_equal(_display_pixels(), _tiled(frames.get_images()))
    assert human.render() is None
    assert human.env_method("render", indices=[0]) == [None]
    human.close()


@pytest.mark.parametrize("mode", ["human", "rgb_array", "rgb_array_list"])
@pytest.mark.parametrize("env_id", ALL_IDS)
def test_gymnasium_make_vec_renders_every_mode(env_id, mode):
    pytest.importorskip("pygame")
    steps = 2
    ours = gymnasium.make_vec(env_id, 3, render_mode=mode)
    ours.reset(seed=0)
    for action in actions(ours, steps, seed=2):
        ours.step(action)
    frames = ours.render()
    if mode == "human":  # the window shows our envs (before Gymnasium's human envs take the display)
        np.testing.assert_array_equal(_display_pixels(), _tiled([ours.frame(index) for index in range(3)]))
        ours.close()
    # The reference: Gymnasium's SyncVectorEnv; in rgb_array_list, Gymnasium's own vector
    # env where its id has one (CartPole: one array per env, as its vector wrappers take
    # them), else its rgb_array envs.
    name = SPECS[env_id].name
    reference_mode, vectorization_mode = mode, "sync"
    if mode == "rgb_array_list":
        if gymnasium.spec(name).vector_entry_point is not None:
            vectorization_mode = "vector_entry_point"
        else:
            reference_mode = "rgb_array"
    reference = gymnasium.make_vec(name, 3, render_mode=reference_mode, vectorization_mode=vectorization_mode)
    assert ours.render_mode == mode and reference.render_mode == reference_mode
    reference.reset(seed=0)
    for action in actions(reference, steps, seed=2):
        reference.step(action)
    ref_frames = reference.render()
    assert type(frames) is type(ref_frames) or mode != "human"
    assert len(frames) == len(ref_frames) == 3
    if mode == "human":
        assert frames == ref_frames == (None,) * 3
    else:
        for index, (frame, ref_frame) in enumerate(zip(frames, ref_frames, strict=True)):
            assert isinstance(frame, np.ndarray)
            assert frame.shape == ref_frame.shape and frame.dtype == ref_frame.dtype
            np.testing.assert_array_equal(frame, ours.frame(index))
    ours.close(), reference.close()


def test_human_rendering_over_an_rgb_array_list_vector_env():
    # Gymnasium's own test (tests/wrappers/vector/test_human_rendering.py::test_render_modes)
    # over our id: its HumanRendering takes one array per env from `render`.
    pytest.importorskip("pygame")
    pytest.importorskip("cv2", reason="Gymnasium's HumanRendering resizes with OpenCV (the test extra has it)")
    from gymnasium.wrappers.vector import HumanRendering

    envs = HumanRendering(gymnasium.make_vec("lerax_like/CartPole-v1", num_envs=3, render_mode="rgb_array_list"))
    assert envs.render_mode == "human"
    envs.reset(seed=0)
    for _ in range(25):
        envs.step(envs.action_space.sample())
    # The window holds the three envs' frames, tiled as the wrapper tiles them (two by two here).
    frames = envs.env.render()
    window = _display_pixels()
    height, width = frames[0].shape[:2]
    assert window.shape == (height, width, 3)
    assert np.any(window != window[0, 0])  # drawn, not a blank window
    envs.close()
    # HumanRendering on a human env is refused, as over Gymnasium's.
    with pytest.raises((AssertionError, ValueError), match=r"Expected env.render_mode to be one of .* but got 'human'"):
        HumanRendering(envs)


def test_sync_vector_env_of_our_envs_collects_each_envs_frames():
    # `vectorization_mode="sync"`: `gymnasium.make`'s single envs, each with RenderCollection,
    # which clears an env's frames at its reset: an env that restarts keeps only the fresh one.
    env_id = "lerax_like/CartPole-v1"
    for mode in (gymnasium.vector.AutoresetMode.NEXT_STEP, gymnasium.vector.AutoresetMode.SAME_STEP):
        ours, reference = (
            gymnasium.make_vec(
                each, 2, render_mode="rgb_array_list", vectorization_mode="sync",
                vector_kwargs={"autoreset_mode": mode}, max_episode_steps=2,
            )
            for each in (env_id, SPECS[env_id].name)
        )
        ours.reset(seed=0), reference.reset(seed=0)
        lengths, ref_lengths = [], []
        for _ in range(4):
            ours.step(np.array([0, 1])), reference.step(np.array([0, 1]))
            frames, ref_frames = ours.render(), reference.render()
            lengths.append([len(each) for each in frames])
            ref_lengths.append([len(each) for each in ref_frames])
            for each, ref_each in zip(frames, ref_frames, strict=True):
                for frame, ref_frame in zip(each, ref_each, strict=True):
                    np.testing.assert_array_equal(frame, ref_frame)
        assert lengths == ref_lengths, mode
        ours.close(), reference.close()


@pytest.mark.slow  # 3.3 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_per_env_parameters_in_float32_and_through_pickle():
    import pickle

    env_id = "lerax_like/CartPole-v1"
    double, _ = pair(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        single = make_vec_env(env_id, NUM_ENVS, seed=7, dtype="float32")
    for venv in (double, single):
        venv.set_attr("masspole", 0.5, indices=[1])
        venv.reset()
    # SB3's VecMonitor does not pickle (a mappingproxy); the vector env inside it does.
    copy = pickle.loads(pickle.dumps(double.venv))
    assert copy.get_attr("masspole") == [0.1, 0.5, 0.1]
    for action in actions(double, 5, seed=4):
        observation, _, _, _ = double.step(action)
        copied, _, _, _ = copy.step(action)
        narrow, _, _, _ = single.step(action)
        np.testing.assert_array_equal(copied, observation)  # the copy continues exactly
        # float32 steps follow float64 ones to float32 rounding, the changed env included.
        np.testing.assert_allclose(narrow, observation, rtol=1e-5, atol=1e-6)
