"""Adaptive model-predictive control (IDS): plan with iLQR through a model env, act on
the real env, refit the model's physical parameters from the transitions seen.

The task as the controller sees it (stage and terminal costs, a success test) is the
caller's: `notebooks/double_cartpole_adaptive_mpc.ipynb` writes the double cart-pole
swing-up's.
"""

from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from .._types import Array, BoolScalar, Float, Key, Scalar
from ..env import AbstractEnv, EnvState
from ..integrate import with_adjoint
from .identification import fit_parameters
from .ilqr import ilqr


def make_planner(
    stage_cost: Callable[[Float[Array, " n"], Float[Array, " m"]], Scalar],
    terminal_cost: Callable[[Float[Array, " n"]], Scalar],
):
    """`plan(model, y, warm_start, iterations) -> (actions, cost)`, compiled once.

    iLQR over the horizon of `warm_start` through the model env's transitions, minimising
    the sum of `stage_cost(y, action)` along it plus `terminal_cost(y_final)`.

    The model's integrator gets diffrax's `ForwardMode` adjoint: iLQR linearises each step
    with `jax.jacfwd`.
    """

    @eqx.filter_jit
    def plan(model: AbstractEnv, y, actions, iterations):
        model = with_adjoint(model, diffrax.ForwardMode())
        key = jr.key(0)  # deterministic transitions: the key is unused

        def step(y, action):
            state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
            return model.transition(state, action, key=key)[0].y

        return ilqr(step, stage_cost, terminal_cost, y, actions, iterations=iterations)

    return plan


def adaptive_mpc(
    real: AbstractEnv,
    model: AbstractEnv,
    where: Callable[[AbstractEnv], tuple],
    *,
    key: Key,
    planner: Callable,
    success: Callable[[Float[Array, " n"]], BoolScalar],
    horizon: int = 60,
    iterations: int = 10,
    first_iterations: int = 100,
    episode_steps: int = 160,
    max_episodes: int = 3,
    success_steps: int = 20,
    refit: bool = True,
    verbose: bool = False,
) -> dict:
    """Closed-loop iLQR-MPC episodes on `real`, refitting `where(model)` after each episode.

    `planner` is `make_planner(stage_cost, terminal_cost)` with the task's costs.
    An episode succeeds when `success(y)` holds for `success_steps` consecutive steps;
    the run stops at the first successful episode. Every transition seen so far (all
    episodes) is used for the refit (`fit_parameters` with one-step residuals).
    Returns `episodes` (run), `transitions` (real steps taken until success, or in all),
    `succeeded`, the parameter estimates after each refit and per-episode traces.
    """
    dtype = real.dt.dtype
    step = eqx.filter_jit(lambda env, s, a, k: env.transition(s, a, key=k)[0])
    seen_states, seen_actions = [], []
    estimates = [where(model)]
    transitions = 0
    report = {"succeeded": False, "episode_traces": []}
    for episode in range(max_episodes):
        key, reset_key = jr.split(key)
        state = real.initial(key=reset_key)
        # A pumping warm start (period 1.5 s) breaks the symmetry of the hanging
        # equilibrium, where the gradient of the cost vanishes.
        times = jnp.arange(horizon, dtype=dtype) * real.dt
        actions = (0.5 * jnp.sin(2 * jnp.pi * times / 1.5))[:, None]
        actions, _ = planner(model, state.y, actions, jnp.asarray(first_iterations))
        ys, taken = [state.y], []
        consecutive = 0
        succeeded = False
        for _ in range(episode_steps):
            actions, _ = planner(model, state.y, actions, jnp.asarray(iterations))
            key, step_key = jr.split(key)
            state = step(real, state, actions[0], step_key)
            transitions += 1
            ys.append(state.y)
            taken.append(actions[0])
            actions = jnp.concatenate([actions[1:], jnp.zeros((1, 1), dtype)])
            consecutive = consecutive + 1 if bool(success(state.y)) else 0
            if consecutive >= success_steps:
                succeeded = True
                break
        ys, taken = jnp.stack(ys), jnp.stack(taken)
        report["episode_traces"].append({"states": np.asarray(ys), "actions": np.asarray(taken)})
        if verbose:
            print(f"episode {episode + 1}: {'succeeded' if succeeded else 'failed'} after {len(taken)} steps")
        if succeeded:
            report["succeeded"] = True
            break
        seen_states.append(ys)
        seen_actions.append(taken)
        if refit:
            # One-step residuals over every transition seen (episodes may differ in length):
            # each transition is a trajectory of one step, fitted with a window of 1.
            pairs = jnp.concatenate([jnp.stack([s[:-1], s[1:]], axis=1) for s in seen_states])
            pair_actions = jnp.concatenate(seen_actions)[:, None, :]
            model, _ = fit_parameters(model, where, pairs, pair_actions, window=1, max_steps=50)
            estimates.append(where(model))
            if verbose:
                print("  refitted:", jax.tree.map(np.asarray, where(model)))
    report.update(episodes=episode + 1, transitions=transitions, estimates=estimates, model=model)
    return report

