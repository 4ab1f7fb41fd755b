"""A batch of envs with different parameters steps in one compiled call, element by element exact."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll


@pytest.mark.slow  # 2.9 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_batch_of_256_pole_masses_equals_single_steps():
    masses = jnp.linspace(0.05, 3.0, 256)
    envs = eqx.filter_vmap(lambda m: ll.make("CartPole", pole_mass=m))(masses)
    keys = jax.random.split(jax.random.key(0), 256)
    step_keys = jax.random.split(jax.random.key(1), 256)
    actions = jax.random.randint(jax.random.key(2), (256,), 0, 2)

    @eqx.filter_jit
    def reset_and_step(env, key, action, step_key):
        state, _, _ = env.reset(key=key)
        return env.step(state, action, key=step_key)

    batched = eqx.filter_vmap(reset_and_step)(envs, keys, actions, step_keys)
    for i in (0, 1, 100, 255):
        single = reset_and_step(ll.make("CartPole", pole_mass=masses[i]), keys[i], actions[i], step_keys[i])
        for batched_leaf, single_leaf in zip(jax.tree.leaves(batched), jax.tree.leaves(single)):
            np.testing.assert_allclose(np.asarray(batched_leaf)[i], np.asarray(single_leaf), rtol=1e-14, atol=0)
    # Different masses really give different motion.
    observations = np.asarray(batched[1])
    assert np.unique(observations[:, 3]).size > 200


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_step_is_pure_under_jit_vmap_and_grad(getkey):
    env = ll.make("CartPoleContinuous", reward="smooth", theta_threshold_radians=jnp.inf, x_threshold=jnp.inf)
    state, _, _ = env.reset(key=getkey())
    key = getkey()

    def total_reward(env, actions):
        def body(state, action):
            state, _, reward, _, _, _ = env.step(state, action, key=key)
            return state, reward

        return jnp.sum(jax.lax.scan(body, state, actions)[1])

    actions = jnp.zeros((20, 1))
    value, grads = eqx.filter_jit(eqx.filter_value_and_grad(total_reward))(env, actions)
    again = eqx.filter_jit(total_reward)(env, actions)
    assert float(value) == float(again)
    assert np.isfinite(float(grads.dynamics.pole_mass)) and float(grads.dynamics.pole_mass) != 0.0
