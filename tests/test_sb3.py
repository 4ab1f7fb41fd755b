"""`lerax_like.sb3`: SB3's vector env API and semantics, against SB3's own `DummyVecEnv`.

The reference is SB3's `make_vec_env` (a `DummyVecEnv` of monitored `gymnasium.make`
envs), run alongside on the same seeds and actions: for CartPole over Gymnasium's own
env (equal observations, bit for bit), for every id over `lerax_like`'s single env.
"""

import os
import subprocess
import sys

import gymnasium
import numpy as np
import pytest

import lerax_like
from lerax_like.gym import SPECS


sb3 = pytest.importorskip("stable_baselines3")
from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env  # noqa: E402
from stable_baselines3.common.vec_env import VecEnv  # noqa: E402


os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
# The ids standing for Gymnasium's envs, tested against them (the others: tests/test_render.py).
ALL_IDS = tuple(env_id for env_id, spec in SPECS.items() if spec.stands_for_gymnasium)


def _balance(observations, rng):
    """CartPole actions that mostly balance, with random pushes: falls and time limits both occur."""
    x, x_dot, theta, theta_dot = np.asarray(observations, dtype=np.float64).T
    balance = (theta + 0.5 * theta_dot + 0.01 * x + 0.05 * x_dot > 0).astype(np.int64)
    return np.where(rng.random(balance.size) < 0.6, rng.integers(0, 2, balance.size), balance)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_sb3_check_env_passes_on_the_single_env(env_id):
    env = gymnasium.make(env_id)
    with np.errstate(all="ignore"):
        check_env(env, warn=True, skip_render_check=True)
    env.close()


@pytest.mark.parametrize("hand_out_generators_at", [None, 150])
def test_same_step_autoreset_matches_dummy_vec_env_on_gymnasium_cartpole(hand_out_generators_at):
    # Our VecEnv draws each env's next start ahead, when its episode starts; once its
    # generators are handed out (`get_attr("np_random")`), it draws a start when the env
    # restarts. Either way, the numbers and the generators' states are DummyVecEnv's.
    num_envs, steps = 6, 400
    kwargs = {"max_episode_steps": 60}
    ours = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=num_envs, seed=11, env_kwargs=kwargs)
    reference = sb3_make_vec_env("CartPole-v1", n_envs=num_envs, seed=11, env_kwargs=kwargs)
    assert isinstance(ours, VecEnv) and ours.num_envs == num_envs
    assert ours.observation_space == reference.observation_space
    assert ours.action_space == reference.action_space
    observation, ref_observation = ours.reset(), reference.reset()
    np.testing.assert_array_equal(observation, ref_observation)
    rng = np.random.default_rng(0)
    counts = {"terminated": 0, "truncated": 0}
    for step in range(steps):
        if step == hand_out_generators_at:
            generators, ref_generators = ours.get_attr("np_random"), reference.get_attr("np_random")
            for generator, ref_generator in zip(generators, ref_generators, strict=True):
                assert generator.bit_generator.state == ref_generator.bit_generator.state
        actions = _balance(ref_observation, rng)
        observation, reward, done, infos = ours.step(actions)
        ref_observation, ref_reward, ref_done, ref_infos = reference.step(actions)
        context = f"step {step}"
        # Exact: the same float64 Euler step, and starts from the same generators.
        np.testing.assert_array_equal(observation, ref_observation, err_msg=context)
        np.testing.assert_array_equal(reward, ref_reward, err_msg=context)
        np.testing.assert_array_equal(done, ref_done, err_msg=context)
        assert observation.dtype == ref_observation.dtype and reward.dtype == ref_reward.dtype
        assert done.dtype == ref_done.dtype
        for index in range(num_envs):
            info, ref_info = infos[index], ref_infos[index]
            assert info["TimeLimit.truncated"] == ref_info["TimeLimit.truncated"], context
            assert ("terminal_observation" in info) == ("terminal_observation" in ref_info) == done[index], context
            if done[index]:
                np.testing.assert_array_equal(info["terminal_observation"], ref_info["terminal_observation"])
                # The returned observation is the next episode's first (same-step autoreset).
                assert not np.array_equal(observation[index], info["terminal_observation"])
                assert info["episode"]["r"] == ref_info["episode"]["r"], context
                assert info["episode"]["l"] == ref_info["episode"]["l"], context
                counts["truncated" if info["TimeLimit.truncated"] else "terminated"] += 1
            assert info["solver_ok"]
    assert counts["terminated"] > 10 and counts["truncated"] > 10, counts  # both ends, and their restarts


@pytest.mark.slow  # 3.0 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_a_stochastic_scene_restarts_in_the_step_as_in_a_second_call(noisy_cartpole):
    # The restart in the step (starts drawn ahead) against the restart in a call of its
    # own (generators handed out): the same starts, and the same keys for the noise.
    def run(hand_out_generators):
        venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=4, seed=3)
        venv.venv.scene = noisy_cartpole(max_episode_steps=12)
        if hand_out_generators:
            venv.get_attr("np_random")
        results = [venv.reset()]
        rng = np.random.default_rng(1)
        for _ in range(40):
            observation, reward, done, infos = venv.step(rng.integers(0, 2, size=4))
            terminal = [info.get("terminal_observation") for info in infos]
            results.append((observation, reward, done, terminal, venv.venv.state.T))  # (num_envs, n)
        return results

    ahead, after = run(False), run(True)
    np.testing.assert_array_equal(ahead[0], after[0])
    restarts = 0
    for step, (ours, theirs) in enumerate(zip(ahead[1:], after[1:])):
        for value, reference in zip(ours, theirs):
            if isinstance(value, list):
                for one, other in zip(value, reference):
                    assert (one is None) == (other is None), step
                    if one is not None:
                        np.testing.assert_array_equal(one, other, err_msg=f"step {step}")
            else:
                np.testing.assert_array_equal(value, reference, err_msg=f"step {step}")
        restarts += int(ours[2].sum())
        noise = ours[0] - ours[4].astype(np.float32)
        assert 1e-5 < np.max(np.abs(noise)) < 1e-2  # the observations are noisy, fresh ones too
    assert restarts >= 8


@pytest.mark.slow  # 6.2 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_a_pickled_vec_env_continues_exactly_in_a_process_without_float64(tmp_path):
    # The starts drawn ahead travel as NumPy and go to the device again on load, in float64,
    # even where JAX's default precision is float32: restarts continue DummyVecEnv's numbers.
    import pickle

    venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=4, seed=2, env_kwargs={"max_episode_steps": 9})
    venv.reset()
    rng = np.random.default_rng(0)
    for _ in range(13):
        venv.step(rng.integers(0, 2, size=4))
    actions = rng.integers(0, 2, size=(30, 4))
    (tmp_path / "venv.pkl").write_bytes(pickle.dumps(venv.venv))
    np.save(tmp_path / "actions.npy", actions)
    expected, dones = zip(*(venv.step(action)[::2] for action in actions))
    script = (
        "import pickle, sys, numpy as np, jax\n"
        "assert not jax.config.jax_enable_x64\n"
        "venv = pickle.loads(open(sys.argv[1] + '/venv.pkl', 'rb').read())\n"
        "actions = np.load(sys.argv[1] + '/actions.npy')\n"
        "np.save(sys.argv[1] + '/loaded.npy', np.array([venv.step(a)[0] for a in actions]))\n"
    )
    subprocess.run([sys.executable, "-c", script, str(tmp_path)], check=True, env={**os.environ, "JAX_ENABLE_X64": "0"})
    loaded = np.load(tmp_path / "loaded.npy")
    assert np.sum(dones) >= 8  # restarts happen in the loaded run, from starts drawn before the pickle
    np.testing.assert_array_equal(loaded, np.array(expected))


def test_an_inadmissible_action_in_an_int64_array_is_refused_and_nothing_steps():
    # An int64 array of the envs' shape goes to the step unchecked; the step checks it.
    venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=3, seed=0)
    twin = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=3, seed=0)
    venv.reset(), twin.reset()
    for bad in (np.array([0, 2, 1]), np.array([-1, 0, 1])):
        index = int(np.flatnonzero((bad < 0) | (bad > 1))[0])
        with pytest.raises(ValueError, match=rf"actions\[{index}\] = {bad[index]} is not in Discrete\(2\)"):
            venv.step(bad)
    for _ in range(30):
        actions = np.array([1, 0, 1])
        for one, other in zip(venv.step(actions)[:3], twin.step(actions)[:3]):
            np.testing.assert_array_equal(one, other)


@pytest.mark.parametrize("env_id", ALL_IDS)
def test_every_id_steps_as_dummy_vec_env_of_its_single_env(env_id):
    # SB3's make_vec_env over `gymnasium.make("lerax_like/<id>")`: our single env, one by one.
    num_envs, steps = 3, 40
    kwargs = {"max_episode_steps": 15}
    ours = lerax_like.sb3.make_vec_env(env_id, n_envs=num_envs, seed=5, env_kwargs=kwargs)
    reference = sb3_make_vec_env(env_id, n_envs=num_envs, seed=5, env_kwargs=kwargs)
    np.testing.assert_array_equal(ours.reset(), reference.reset())  # the same starts
    reference.action_space.seed(0)
    ends = 0
    for step in range(steps):
        actions = np.stack([reference.action_space.sample() for _ in range(num_envs)])
        observation, reward, done, infos = ours.step(actions)
        ref_observation, ref_reward, ref_done, ref_infos = reference.step(actions)
        context = f"{env_id} step {step}"
        # The batched and the single compiled step may round differently (XLA vectorises
        # the batch): float32 observations agree to a few of their ulps.
        np.testing.assert_allclose(observation, ref_observation, rtol=4 * 2**-23, atol=1e-6, err_msg=context)
        np.testing.assert_allclose(reward, ref_reward, rtol=1e-6, atol=1e-6, err_msg=context)
        np.testing.assert_array_equal(done, ref_done, err_msg=context)
        for info, ref_info in zip(infos, ref_infos):
            assert info["TimeLimit.truncated"] == ref_info["TimeLimit.truncated"], context
            assert info["solver_steps"] == ref_info["solver_steps"] and info["solver_ok"] == ref_info["solver_ok"]
            if "terminal_observation" in ref_info:
                np.testing.assert_allclose(
                    info["terminal_observation"], ref_info["terminal_observation"], rtol=4 * 2**-23, atol=1e-6
                )
        ends += int(done.sum())
    assert ends >= num_envs * 2  # every env restarted (time limit 15, 40 steps)


def test_vec_env_attributes_seeds_and_bad_arguments():
    venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=4, seed=0)
    assert venv.get_attr("render_mode") == ["rgb_array"] * 4
    # Monitored, as SB3's make_vec_env's envs are (a Monitor is a gymnasium.Wrapper).
    assert venv.env_is_wrapped(gymnasium.Wrapper) == [True] * 4
    first = venv.reset()
    venv.seed(0)
    np.testing.assert_array_equal(venv.reset(), first)  # the same seeds, the same starts
    assert not np.array_equal(venv.reset(), first)  # no seed: the generators go on
    images = venv.get_images()
    assert len(images) == 4 and images[0].dtype == np.uint8
    # A scene of other parameters for some envs (tests/test_sb3_contract.py steps them);
    # one of another configuration (a solver) would need another program: refused.
    heavy = lerax_like.make("CartPole", pole_mass=0.5)
    venv.set_attr("scene", heavy, indices=[0])
    assert [scene is heavy for scene in venv.get_attr("scene")] == [True, False, False, False]
    with pytest.raises(ValueError, match="more than its array parameters"):
        venv.set_attr("scene", lerax_like.make("CartPole", solver="rk4"), indices=[1])
    with pytest.raises(ValueError, match="env_id must be one of"):
        lerax_like.sb3.make_vec_env("CartPole-v1", n_envs=2)
    with pytest.raises(ValueError, match="wrapper_class"):
        lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=2, wrapper_class=gymnasium.Wrapper)
    with pytest.raises(ValueError, match="n_envs"):
        lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=0)
    with pytest.raises(ValueError, match="dtype must be one of"):
        lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=2, dtype="float16")


def test_float32_vec_env_follows_float64_to_float32_precision():
    kwargs = {"max_episode_steps": 1000}
    ours32 = lerax_like.sb3.make_vec_env("lerax_like/Pendulum-v1", n_envs=4, seed=1, env_kwargs=kwargs, dtype="float32")
    ours64 = lerax_like.sb3.make_vec_env("lerax_like/Pendulum-v1", n_envs=4, seed=1, env_kwargs=kwargs)
    # The starts are drawn in float64 and rounded: cos and sin of them agree to float32 precision.
    np.testing.assert_allclose(ours32.reset(), ours64.reset(), rtol=2**-23, atol=1e-6)
    for _ in range(5):  # a few steps stay close
        actions = np.array([[-2.0], [-0.5], [0.5], [2.0]], dtype=np.float32)
        observation32 = ours32.step(actions)[0]
        observation64 = ours64.step(actions)[0]
        np.testing.assert_allclose(observation32, observation64, rtol=1e-4, atol=1e-5)
    assert ours32.get_attr("state")[0].dtype == np.float32
    assert ours64.get_attr("state")[0].dtype == np.float64


@pytest.mark.slow
def test_ppo_trains_on_it():
    from stable_baselines3 import PPO

    venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=2, seed=0)
    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=128)
    assert model.num_timesteps == 128
    assert len(model.ep_info_buffer) > 0  # the episodes' statistics reach SB3 (VecMonitor)


def test_missing_sb3_gets_an_install_hint(monkeypatch):
    for name in [name for name in sys.modules if name.split(".")[0] == "stable_baselines3"]:
        monkeypatch.setitem(sys.modules, name, None)  # makes `import stable_baselines3...` fail
    monkeypatch.delitem(sys.modules, "lerax_like.sb3._vec_env", raising=False)
    monkeypatch.delattr(lerax_like.sb3, "_vec_env", raising=False)
    with pytest.raises(ImportError, match=r"lerax_like\[sb3\]"):
        lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=2)


_DISPATCH = """
import jax
from jax._src import xla_bridge
import lerax_like
import lerax_like.sb3
started_by_import = xla_bridge.backends_are_initialized()
if {jax_first}:
    jax.numpy.ones(1).block_until_ready()  # the process's own JAX work, before the VecEnv
venv = lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=2, seed=0{keywords})
venv.reset()
venv.step(venv.action_space.sample()[None].repeat(2, 0))
print(started_by_import, jax.config.values["jax_cpu_enable_async_dispatch"])
"""


@pytest.mark.parametrize(
    ("jax_first", "keywords", "async_dispatch"),
    [(False, "", False), (False, ", inline_dispatch=False", True), (True, "", True)],
    ids=["default", "opted-out", "jax-started-first"],
)
@pytest.mark.slow  # up to 4.1 s a case of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_make_vec_env_makes_jax_dispatch_inline_only_before_jax_starts(jax_first, keywords, async_dispatch):
    # A fresh process, as a user's script: importing lerax_like does not start JAX's CPU
    # client; the VecEnv then makes its dispatch inline unless told not to, and leaves the
    # flag alone once JAX has started (it would no longer be what the client does).
    code = _DISPATCH.format(jax_first=jax_first, keywords=keywords)
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    started_by_import, flag = completed.stdout.split()
    assert started_by_import == "False"
    assert flag == str(async_dispatch)


def test_inline_dispatch_must_be_a_bool():
    with pytest.raises(ValueError, match="inline_dispatch must be True or False, got 'yes'"):
        lerax_like.sb3.make_vec_env("lerax_like/CartPole-v1", n_envs=1, inline_dispatch="yes")
