"""System identification: fitting an env's physical parameters to observed transitions.

The model of a transition is the env's own step, `env.transition`, so the fit is a
nonlinear least-squares problem whose Jacobian autodiff computes through the solver.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import optimistix

from ..env import AbstractEnv, EnvState
from ..gradients import with_adjoint
from .._types import Array, Float


def one_step_residuals(
    env: AbstractEnv,
    states: Float[Array, "N n"],
    actions: Array,
    next_states: Float[Array, "N n"],
) -> Float[Array, "N n"]:
    """The env's one-step predictions from `states` under `actions`, minus `next_states`."""

    def predict(y, action):
        state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
        return env.transition(state, action, key=jr.key(0))[0].y

    return jax.vmap(predict)(states, actions) - next_states


def fit_parameters(
    env: AbstractEnv,
    where: Callable[[AbstractEnv], Any],
    states: Float[Array, "N n"],
    actions: Array,
    next_states: Float[Array, "N n"],
    *,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_steps: int = 100,
) -> tuple[AbstractEnv, optimistix.Solution]:
    """Fit the parameters `where(env)` to observed transitions by Levenberg--Marquardt.

    The parameters are fitted in log space (they are positive physical quantities, and
    their scales differ); `env`'s values are the initial guess. Residuals are scaled per
    state coordinate by the spread of the observed changes, so that no coordinate
    dominates because of its units. Returns the fitted env (with the forward adjoint) and optimistix's solution.
    """
    # Levenberg--Marquardt builds the Jacobian column by column with forward mode; a few
    # parameters make that the cheap direction, and it needs diffrax's ForwardMode.
    env = with_adjoint(env, "forward")
    scale = jnp.std(next_states - states, axis=0) + jnp.finfo(states.dtype).eps
    initial = jax.tree.map(jnp.log, where(env))

    def residuals(log_parameters, _):
        fitted = eqx.tree_at(where, env, jax.tree.map(jnp.exp, log_parameters))
        return one_step_residuals(fitted, states, actions, next_states) / scale

    solution = optimistix.least_squares(
        residuals,
        optimistix.LevenbergMarquardt(rtol=rtol, atol=atol),
        initial,
        max_steps=max_steps,
        throw=False,
    )
    fitted = eqx.tree_at(where, env, jax.tree.map(jnp.exp, solution.value))
    return fitted, solution
