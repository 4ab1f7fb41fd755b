"""Recover physical parameters of an env from observed state trajectories.

The model is the env itself with some leaves replaced (`where`, as in `eqx.tree_at`).
Residuals are those of multiple shooting: from every observed state the model is rolled
`window` steps with the recorded actions and compared with the next observed states.
Short windows keep the loss close to quadratic in the parameters even for chaotic
systems, where a single long rollout has a loss landscape full of local minima.
"""

from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import optimistix as optx

from .._types import Array, Float
from ..env import AbstractEnv, EnvState, rollout
from ..integrate import with_adjoint


def multiple_shooting_residuals(
    env: AbstractEnv,
    states: Float[Array, "batch T+1 n"],
    actions: Float[Array, "batch T m"],
    window: int,
) -> Float[Array, "batch starts window n"]:
    """Model rollouts of `window` steps from every observed state, minus the observations.

    `states[b, k + 1]` is what followed `states[b, k]` under `actions[b, k]`. Every start
    `k` in `0 .. T - window` is used.
    """
    n_steps = actions.shape[1]
    if not 1 <= window <= n_steps:
        raise ValueError(f"window must be between 1 and the trajectory length {n_steps}, got {window}")
    starts = jnp.arange(n_steps - window + 1)
    key = jr.key(0)  # transitions of these envs are deterministic; the key is unused.

    def one_window(trajectory, trajectory_actions, start):
        y0 = trajectory[start]
        window_actions = jax.lax.dynamic_slice_in_dim(trajectory_actions, start, window)
        # Per-step checkpointing (rollout's default) saves memory over long horizons only; over a
        # fit's short windows it saves nothing and moves the gradient's round-off, which the
        # adaptive MPC's chaotic swing-up (tests/test_chain.py) amplifies into a miss.
        state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
        predicted, _ = rollout(env, state, window_actions, key=key, checkpoint=False)
        return predicted - jax.lax.dynamic_slice_in_dim(trajectory, start + 1, window)

    per_trajectory = jax.vmap(one_window, in_axes=(None, None, 0))
    return jax.vmap(per_trajectory, in_axes=(0, 0, None))(states, actions, starts)


def fit_parameters(
    env: AbstractEnv,
    where: Callable[[AbstractEnv], Array | tuple[Array, ...]],
    states: Float[Array, "batch T+1 n"],
    actions: Float[Array, "batch T m"],
    *,
    window: int = 5,
    scale: Float[Array, " n"] | None = None,
    max_steps: int = 100,
    rtol: float = 1e-10,
    atol: float = 1e-10,
) -> tuple[AbstractEnv, optx.Solution]:
    """Fit the positive parameters `where(env)` (an array or a tuple of them) to observed trajectories.

    Least squares over the multiple-shooting residuals, by Levenberg-Marquardt
    (Jacobian by forward-mode autodiff through the
    integrator: few parameters, many residuals; the env's integrator is given diffrax's
    `ForwardMode` adjoint for this), in log parameters so
    that masses and lengths stay positive. Returns the fitted env and optimistix's
    solution (`solution.stats["num_steps"]`, `solution.result`). `scale` divides the
    residuals per state coordinate, so that no coordinate dominates by its units.
    """

    env = with_adjoint(env, diffrax.ForwardMode())

    def residuals(log_parameters, _):
        model = eqx.tree_at(where, env, jax.tree.map(jnp.exp, log_parameters))
        residual = multiple_shooting_residuals(model, states, actions, window)
        return residual if scale is None else residual / scale

    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    solution = optx.least_squares(
        residuals, solver, jax.tree.map(jnp.log, where(env)), max_steps=max_steps, throw=False
    )
    return eqx.tree_at(where, env, jax.tree.map(jnp.exp, solution.value)), solution


def _as_trajectories(states, actions, next_states):
    # N transitions are N trajectories of one step.
    return jnp.stack([states, next_states], axis=1), actions[:, None]


def one_step_residuals(
    env: AbstractEnv,
    states: Float[Array, "N n"],
    actions: Array,
    next_states: Float[Array, "N n"],
) -> Float[Array, "N n"]:
    """The env's one-step predictions from `states` under `actions`, minus `next_states`."""
    trajectories, trajectory_actions = _as_trajectories(states, actions, next_states)
    return multiple_shooting_residuals(env, trajectories, trajectory_actions, window=1)[:, 0, 0]


def fit_transitions(
    env: AbstractEnv,
    where: Callable[[AbstractEnv], Array],
    states: Float[Array, "N n"],
    actions: Array,
    next_states: Float[Array, "N n"],
    **options,
) -> tuple[AbstractEnv, optx.Solution]:
    """`fit_parameters` on observed transitions `states --actions--> next_states`
    (from anywhere in any episodes), residuals scaled by the spread of the observed
    changes per coordinate."""
    trajectories, trajectory_actions = _as_trajectories(states, actions, next_states)
    scale = jnp.std(next_states - states, axis=0) + jnp.finfo(states.dtype).eps
    return fit_parameters(env, where, trajectories, trajectory_actions, window=1, scale=scale, **options)
