"""Gradients of batched rollouts (`jax.vmap` over envs from distinct resets): issue 29.

Every env of a vmapped batch runs every segment of a step with located impacts, the ones
that have finished theirs included; their results are dropped by a select, and in reverse
mode any non-finite partial derivative there turns the dropped value's zero cotangent into
NaN for the whole batch. These tests differentiate batches in which the envs hit a wall at
different steps, so that one env finishes its step while another is still in it.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll


def _walled_cartpole_batch(solver, envs=4):
    # A rail 6 cm either side: from the resets (within 5 cm of the centre) the pushed carts
    # reach the wall at different steps of the rollout.
    env = ll.CartPoleContinuous(restitution=0.8, track_limit=0.06, solver=solver)
    states = jax.vmap(lambda key: env.reset(key=key)[0])(jr.split(jr.key(0), envs))
    return env, states


@pytest.mark.parametrize("solver", ["euler", "rk4"])
def test_batched_reverse_mode_through_walls_is_finite_and_equals_each_envs_own(solver):
    # Issue 29: jax.grad of a vmapped rollout of CartPoleContinuous(restitution=0.8) raised
    # lineax's "non-finite input" (the default Euler, and RK4), one env alone did not.
    env, states = _walled_cartpole_batch(solver)
    actions = jnp.full((12, 1), 0.3)

    def loss(env, state):
        ys, info = ll.rollout(env, state, actions)
        return jnp.sum(ys**2), info["impacts"]

    def batched(env):
        values, impacts = jax.vmap(lambda state: loss(env, state))(states)
        return jnp.sum(values), impacts

    gradient, impacts = eqx.filter_jit(eqx.filter_grad(batched, has_aux=True))(env)
    # The envs hit the wall at different steps, so in some step one env has finished while another has not.
    first_impact = np.argmax(np.asarray(impacts) > 0, axis=1)
    assert np.all(np.asarray(impacts).sum(axis=1) >= 1) and len(set(first_impact.tolist())) > 1, impacts
    single = eqx.filter_jit(eqx.filter_grad(lambda env, state: loss(env, state)[0]))
    for i in range(states.y.shape[0]):
        own = single(env, jax.tree.map(lambda leaf: leaf[i], states))
        batched_leaves, own_leaves = jax.tree.leaves(gradient), jax.tree.leaves(own)
        sum_of_own = own_leaves if i == 0 else [a + b for a, b in zip(sum_of_own, own_leaves)]
    for total, expected in zip(batched_leaves, sum_of_own):
        assert np.all(np.isfinite(total))
        np.testing.assert_allclose(total, expected, rtol=1e-10, atol=1e-12)

