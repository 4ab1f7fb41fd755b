"""The functional API inside a jitted trainer: infos that `lax.scan` and `lax.select` can mix,
the episode limit as data, and space bounds that a trainer reads as NumPy values."""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll
from conftest import quick_unless_hybrid


def _structure(tree):
    """Tree structure, and each leaf's shape, dtype and weak type: what `lax.select` needs equal."""
    leaves, treedef = jax.tree.flatten(tree)
    return treedef, [(jnp.shape(leaf), jnp.result_type(leaf), getattr(leaf, "weak_type", False)) for leaf in leaves]


def _infos(env, key):
    """The info trees of `reset` and of `step`, traced only (`eval_shape`): their structure is all we read."""
    reset_key, action_key, step_key = jr.split(key, 3)
    state, _, reset_info = env.reset(key=reset_key)
    action = env.action_space.sample(key=action_key)
    # Plain `jax` tracing, the env an argument, as a jitted trainer passes it.
    step_info = jax.eval_shape(lambda env, state, action: env.step(state, action, key=step_key)[-1], env, state, action)
    return reset_info, step_info


def _assert_same_info_structure(env, key):
    reset_info, step_info = _infos(env, key)
    assert set(reset_info) == set(step_info)
    assert _structure(reset_info) == _structure(step_info)


# Hybrid scenes' cases are CI's (BouncingBall's 3.2 s of one worker at 4ff5f8c, docs/testing.md).
@pytest.mark.parametrize("name", [quick_unless_hybrid(name) for name in ll.SCENES])
def test_reset_info_has_step_info_structure_every_scene(name, getkey):
    _assert_same_info_structure(ll.SCENES[name](), getkey())


@pytest.mark.parametrize("solver", list(ll.SOLVERS.names))
def test_reset_info_has_step_info_structure_every_preset(solver, getkey):
    _assert_same_info_structure(ll.make("CartPoleContinuous", solver=solver), getkey())


@pytest.mark.slow
@pytest.mark.parametrize("solver", list(ll.SOLVERS.names))
@pytest.mark.parametrize("name", list(ll.SCENES))
def test_reset_info_has_step_info_structure_every_scene_and_preset(name, solver, getkey):
    env = ll.make(name, solver=solver)
    if solver == "semi_implicit_euler" and env.physics.velocity_indices is None:
        # Not a pair that steps: the integrator refuses it by name when the step is traced.
        with pytest.raises(ValueError, match="velocity_indices"):
            _assert_same_info_structure(env, getkey())
        return
    _assert_same_info_structure(env, getkey())


@pytest.mark.slow  # 2.5 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_reset_info_follows_each_env_s_structure_and_float_mode(getkey):
    """`reset` traces a step's info once per structure of env (lerax_like.env._step_info_shapes):
    envs alike but for their contacts, or made in another float mode, each get their own."""
    plain = ll.make("CartPoleContinuous")
    walled = ll.make("CartPoleContinuous", restitution=0.8, track_limit=0.06)
    for env, has_impacts in ((plain, False), (walled, True), (plain, False)):
        _assert_same_info_structure(env, getkey())
        assert ("impacts" in env.reset(key=getkey())[2]) == has_impacts
    with jax.enable_x64(False):
        _, _, info = ll.make("CartPoleContinuous", restitution=0.8, track_limit=0.06).reset(key=jr.key(0))
    assert info["first_impact_time"].dtype == jnp.float32 and info["impacts"].dtype == jnp.int32
    assert walled.reset(key=getkey())[2]["first_impact_time"].dtype == jnp.float64


@pytest.mark.parametrize("name", [quick_unless_hybrid("CartPoleContinuous"), quick_unless_hybrid("BouncingBall")])
def test_an_env_built_in_float32_steps_in_float32_whatever_the_action_s_float_mode(name):
    """An env made under `jax.enable_x64(False)` and stepped in float64 mode, with a float64
    action (what its action space samples there), computes in float32: bit for bit the
    rollout of float32 mode. The action once promoted a smooth scene's state to float64 at
    its first step, and failed to trace a hybrid scene's contact forces (a `cond` whose
    branches were float32 and float64)."""

    @eqx.filter_jit
    def run(env, action):
        state, _, _ = env.reset(key=jr.key(0))

        def body(state, _):
            state, observation, reward, _, _, info = env.step(state, action, key=jr.key(1))
            return state, (observation, reward, info["solver_ok"])

        return jax.lax.scan(body, state, None, length=30)[1]

    with jax.enable_x64(False):
        env = ll.make(name)
        observations32, rewards32, _ = run(env, jnp.full(env.action_space.shape, 0.5))
    observations, rewards, solver_ok = run(env, jnp.full(env.action_space.shape, 0.5, dtype=jnp.float64))
    assert bool(jnp.all(solver_ok)) and observations.dtype == jnp.float32
    np.testing.assert_array_equal(observations, observations32)
    np.testing.assert_array_equal(rewards, rewards32)


def test_reset_info_says_nothing_failed(getkey):
    """A reset integrated nothing: its flags are True, its counts zero, its final observation the start's."""
    env = ll.make("CartPole", solver="tsit5")
    _, observation, info = env.reset(key=getkey())
    assert bool(info["solver_ok"]) and bool(info["action_ok"])
    assert int(info["solver_steps"]) == 0 and int(info["solver_rejected_steps"]) == 0
    np.testing.assert_array_equal(info["final_observation"], observation)


def test_scan_carries_the_info_and_select_mixes_reset_and_step(getkey):
    """A trainer's loop: the carry holds an info, and a done env takes a reset's state and info."""
    env = ll.make("CartPole", solver="rk4", max_episode_steps=7)

    @eqx.filter_jit
    def run(env, key):
        reset_key, key = jr.split(key)
        state, observation, info = env.reset(key=reset_key)

        def body(carry, key):
            state, info = carry
            step_key, reset_key = jr.split(key)
            next_state, _, _, terminated, truncated, next_info = env.step(state, jnp.asarray(1), key=step_key)
            fresh_state, _, fresh_info = env.reset(key=reset_key)
            done = terminated | truncated
            pick = lambda fresh, stepped: jax.lax.select(jnp.broadcast_to(done, jnp.shape(fresh)), fresh, stepped)
            carry = (jax.tree.map(pick, fresh_state, next_state), jax.tree.map(pick, fresh_info, next_info))
            return carry, (done, next_info["solver_steps"])

        _, (done, solver_steps) = jax.lax.scan(body, (state, info), jr.split(key, 20))
        return done, solver_steps

    done, solver_steps = run(env, getkey())
    # Pushing right always, the pole falls (or the limit of 7 ends the episode) well within 20 steps.
    assert bool(jnp.any(done))
    # RK4 takes one step per env step (dt is its step): an independent count, not the code's.
    assert np.all(np.asarray(solver_steps) == 1)


def test_episode_limit_is_data_vmapped(getkey):
    """Limits batched as data in one compiled program: each env truncates at its own limit."""
    limits = jnp.asarray([3, 5, 11])
    # No termination: only the limit ends an episode.
    env = ll.CartPoleContinuous(theta_threshold_radians=jnp.inf, x_threshold=jnp.inf)
    envs = eqx.filter_vmap(lambda limit: eqx.tree_at(lambda e: e.max_episode_steps, env, limit))(limits)

    @eqx.filter_jit
    @eqx.filter_vmap
    def first_truncation(env, key):
        state, _, _ = env.reset(key=key)

        def body(state, index):
            state, _, _, _, truncated, _ = env.step(state, jnp.zeros(1), key=jr.fold_in(key, index))
            return state, truncated

        _, truncated = jax.lax.scan(body, state, jnp.arange(15))
        return jnp.argmax(truncated) + 1

    keys = jr.split(getkey(), 3)
    np.testing.assert_array_equal(first_truncation(envs, keys), limits)
    assert isinstance(env.max_episode_steps, jax.Array) and env.max_episode_steps.dtype == jnp.dtype(int)


@pytest.mark.parametrize("limit", [0, -1, 2.5, "10", (5,)])
def test_bad_episode_limit_is_refused_by_name(limit):
    with pytest.raises(ValueError, match="max_episode_steps must be None or an integer >= 1"):
        ll.CartPole(max_episode_steps=limit)


def test_no_episode_limit():
    env = ll.CartPole(max_episode_steps=None)
    state, _, _ = env.reset(key=jr.key(0))
    assert not bool(env.truncate(eqx.tree_at(lambda s: s.steps, state, jnp.asarray(10**6))))


@pytest.mark.parametrize("name", list(ll.SCENES))
def test_space_bounds_are_numpy_inside_jit(name):
    """A jitted trainer that closes over its env reads the bounds with NumPy, as gymnax's users do."""
    env = ll.SCENES[name]()
    seen = {}

    @jax.jit
    def trainer(x):
        for space_name in ("action_space", "observation_space"):
            space = getattr(env, space_name)
            if isinstance(space, ll.Box):
                seen[space_name] = (np.asarray(space.low), np.asarray(space.high))
        return x

    trainer(0.0)
    for space_name, (low, high) in seen.items():
        space = getattr(env, space_name)  # built eagerly, outside the trace
        np.testing.assert_array_equal(low, space.low)
        np.testing.assert_array_equal(high, space.high)
        assert isinstance(space.low, np.ndarray) and low.shape == space.shape


@pytest.mark.slow  # 3.5 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_space_bounds_follow_traced_parameters():
    """Bounds computed from parameters that are traced (the env an argument of jit) follow them."""
    env = ll.CartPole()
    high = eqx.filter_jit(lambda env: env.observation_space.high)(eqx.tree_at(lambda e: e.x_threshold, env, 3.0))
    assert float(high[0]) == 6.0
