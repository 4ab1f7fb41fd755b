"""Gradients of a 40-step rollout loss against central finite differences in float64."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.env import EnvState


STEPS = 40
Y0 = jnp.array([0.05, -0.1, 0.2, 0.1])


def _loss(env, actions):
    state = EnvState(y=Y0, steps=jnp.zeros((), int))
    ys, infos = ll.rollout(env, state, actions, key=jax.random.key(0))
    # Squared distance from upright and from the rail's centre, plus a terminal cost.
    return jnp.sum(ys[:, 0] ** 2 + ys[:, 2] ** 2) + 10.0 * jnp.sum(ys[-1] ** 2)


def _with_pole_mass(env, pole_mass):
    return eqx.tree_at(lambda e: e.dynamics.pole_mass, env, pole_mass)


@pytest.fixture(scope="module")
def actions():
    # Inside (-1, 1), so the action clip is inactive and the loss is smooth.
    return jax.random.uniform(jax.random.key(1), (STEPS, 1), minval=-0.6, maxval=0.6)


@pytest.mark.parametrize(
    "solver, rtol",
    [("euler", 1e-6), ("rk4", 1e-6), pytest.param("tsit5", 1e-4, marks=pytest.mark.slow)],  # tsit5: about 17 s
)
@pytest.mark.slow  # up to 3.9 s a case of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_gradients_match_central_finite_differences(solver, rtol, actions):
    env = ll.make("CartPoleContinuous", solver=solver, theta_threshold_radians=jnp.inf, x_threshold=jnp.inf)
    loss = eqx.filter_jit(_loss)
    pole_mass = env.dynamics.pole_mass

    grad_mass = jax.jit(jax.grad(lambda m, a: _loss(_with_pole_mass(env, m), a)))(pole_mass, actions)
    h = 1e-6 * float(pole_mass)
    fd_mass = (
        float(loss(_with_pole_mass(env, pole_mass + h), actions)) - float(loss(_with_pole_mass(env, pole_mass - h), actions))
    ) / (2 * h)
    assert abs(float(grad_mass) - fd_mass) <= rtol * abs(fd_mass)

    grad_actions = jax.jit(jax.grad(lambda a: _loss(env, a)))(actions)
    h = 1e-6
    basis = jnp.eye(STEPS)[:, :, None] * h
    batched_loss = jax.jit(jax.vmap(lambda a: _loss(env, a)))
    fd_actions = (batched_loss(actions + basis) - batched_loss(actions - basis)) / (2 * h)
    error = np.max(np.abs(np.asarray(grad_actions[:, 0]) - np.asarray(fd_actions)))
    assert error <= rtol * np.max(np.abs(np.asarray(fd_actions)))
    # Not vacuous: the loss depends on every action.
    assert np.all(np.abs(np.asarray(fd_actions)) > 0)
