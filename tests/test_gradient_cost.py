"""What makes a batched gradient cheap must not change it: checkpointing only recomputes.

`ll.rollout(..., checkpoint=True)` (the default) and the checkpoint count that
`Integrator` gives a `RecursiveCheckpointAdjoint` (`lerax_like.gradients.sized_to_the_work`)
trade memory for recomputation; the values and the reverse-mode gradients, vmapped over envs
from distinct resets, must be those of storing everything, to round-off. Memory is XLA's own
accounting of the compiled gradient (no timing in tests).
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.gradients import CHECKPOINTS

from conftest import tree_allclose

ENVS = 4


def _starts(env):
    return jax.vmap(lambda key: env.reset(key=key)[0])(jr.split(jr.key(3), ENVS))


def _batched_value_and_grad(env, actions, **rollout_options):
    """Value and gradient, with respect to the pole mass and to the start states, of a batched loss."""
    states = _starts(env)

    def loss(pole_mass, ys0):
        scene = eqx.tree_at(lambda e: e.dynamics.pole_mass, env, pole_mass)

        def one(y0):
            state = ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int))
            ys, _ = ll.rollout(scene, state, actions, **rollout_options)
            return jnp.sum(jnp.cos(ys[:, 2])) + jnp.sum(ys[-1] ** 2)

        return jnp.sum(jax.vmap(one)(ys0))

    return jax.jit(jax.value_and_grad(loss, argnums=(0, 1))), (env.dynamics.pole_mass, states.y)


def test_default_adjoint_keeps_few_checkpoints():
    # diffrax would size them by the budget (4096 steps: 90 checkpoints per solve).
    adaptive = ll.make("CartPoleContinuous", solver="tsit5").integrator
    assert adaptive.adjoint.checkpoints == CHECKPOINTS
    assert ll.with_adjoint(ll.make("CartPoleContinuous", solver="tsit5"), "checkpoint").integrator.adjoint.checkpoints == CHECKPOINTS
    # Never more than the budget; an explicit count is the user's.
    assert ll.make("CartPoleContinuous", solver="rk4", substeps=3).integrator.adjoint.checkpoints == 3
    explicit = ll.make("CartPoleContinuous", solver="tsit5", adjoint=diffrax.RecursiveCheckpointAdjoint(checkpoints=50))
    assert explicit.integrator.adjoint.checkpoints == 50


@pytest.mark.slow  # two adaptive gradients compiled
# Two programs that compute the same gradient, to 1e-13: with the suite's XLA flags they round
# apart by more (docs/testing.md).
@pytest.mark.xla_defaults
def test_recomputed_solves_give_the_same_gradient():
    # A long env step at tight tolerances takes far more solver steps than the default
    # checkpoints can hold (8 hold up to 44 without extra recomputation), so reverse mode
    # recomputes; the gradient must be the one of storing every step.
    controller = diffrax.PIDController(rtol=1e-11, atol=1e-13)
    actions = jnp.array([[0.4], [-0.6]])
    few = ll.make("CartPoleContinuous", solver="tsit5", stepsize_controller=controller, dt=0.5, reward="smooth")
    every = ll.make("CartPoleContinuous",
        solver="tsit5", stepsize_controller=controller, dt=0.5, reward="smooth",
        adjoint=diffrax.RecursiveCheckpointAdjoint(checkpoints=400),
    )
    steps = jax.vmap(lambda s: ll.rollout(few, s, actions)[1]["solver_steps"])(_starts(few))
    assert int(jnp.min(steps)) > 44
    function, arguments = _batched_value_and_grad(few, actions)
    value_few, gradient_few = function(*arguments)
    function, arguments = _batched_value_and_grad(every, actions)
    value_every, gradient_every = function(*arguments)
    assert tree_allclose(value_few, value_every, rtol=1e-14)
    assert tree_allclose(gradient_few, gradient_every, rtol=1e-13, atol=1e-13)


@pytest.mark.slow  # two adaptive gradients compiled
def test_rollout_checkpointing_changes_memory_not_gradients():
    env = ll.make("CartPoleContinuous", solver="tsit5", reward="smooth")
    actions = jnp.linspace(-0.8, 0.7, 6)[:, None]
    results, memory = {}, {}
    for checkpoint in (True, False):
        function, arguments = _batched_value_and_grad(env, actions, checkpoint=checkpoint)
        compiled = function.lower(*arguments).compile()
        memory[checkpoint] = compiled.memory_analysis().temp_size_in_bytes
        results[checkpoint] = compiled(*arguments)
    assert tree_allclose(results[True], results[False], rtol=1e-14, atol=1e-15)
    assert np.all(np.isfinite(np.asarray(results[True][1][1])))
    # Only the states between steps are kept, not each step's solver internals.
    assert memory[True] < memory[False]
