"""The objective of the gradient-variance study: the quadratic cost of a rollout under a policy.

`f(theta) = sum_k dt (state_weight |y_{k+1}|^2 + action_weight |a_k|^2)` over `H` env steps
from a fixed start, through the scene's own `transition`; `theta` sets the actions as an
open-loop sequence or the gain of a linear state feedback (`POLICIES`). Every function takes
values (a scene's name and keywords, an env, a start, weights), not the study's configuration.
"""

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax.tree_util import Partial

from ..._types import Array, BoolScalar, Float
from ...env import AbstractEnv, EnvState
from ...spaces import Box
from ..scenes import make


POLICIES: tuple[str, ...] = ("open_loop", "linear_feedback")
"""How `theta` sets the actions: `open_loop`, `a_k = theta[k]` (shape `(H, m)`);
`linear_feedback`, `a_k = theta @ y_k` (shape `(m, n)`)."""


def _cast(tree, dtype):
    """Every floating-point leaf of `tree` in `dtype`."""
    return jax.tree.map(lambda x: x.astype(dtype) if eqx.is_inexact_array(x) else x, tree)


def build_env(scene: str, scene_kwargs: Mapping[str, Any], solver: str, dtype: str) -> AbstractEnv:
    """The env `scene` built with `scene_kwargs` and `solver` (a preset name), its leaves in `dtype`.

    Refuses a scene with discrete actions or one that clips or wraps its state.
    """
    kwargs = {key: value for key, value in scene_kwargs.items() if key != "solver"}
    with jax.enable_x64(True):
        env = make(scene, solver=solver, **kwargs)
    if not isinstance(env.action_space, Box):
        raise ValueError(
            f"{scene} has discrete actions; the gradient-variance study needs continuous ones "
            "(use CartPoleContinuous for CartPole)"
        )
    if type(env).projects_state():
        raise ValueError(
            f"{scene} clips or wraps its state after every step (its `project`), so the rollout "
            "cost has kinks that are no part of the physics; the study takes scenes that do not"
        )
    return _cast(env, jnp.dtype(dtype))


def initial_state(env: AbstractEnv, start: Sequence[float] | None, seed: int) -> Array:
    """The fixed start `start` in the env's dtype (None: `env.initial` at `seed`)."""
    dtype = env.dt.dtype
    if start is None:
        return env.initial(key=jr.key(seed)).y.astype(dtype)
    y0 = jnp.asarray(np.asarray(start, dtype=np.float64), dtype=dtype)
    if y0.shape != env.initial(key=jr.key(0)).y.shape:
        raise ValueError(f"initial_state must have shape {env.initial(key=jr.key(0)).y.shape}, got {y0.shape}")
    return y0


def action_size(env: AbstractEnv) -> int:
    """The number of action components of `env`."""
    return int(np.prod(env.action_space.shape))


def policy_action(kind: str, theta: Array, y: Array, k) -> Array:
    """The action of policy `kind` with parameters `theta` in state `y` at env step `k`."""
    if kind == "open_loop":
        return theta[k]
    return theta @ y


def step_state(env: AbstractEnv, y: Array, action: Array) -> tuple[Array, BoolScalar]:
    """One env step from `y` under `action`, with no termination: the next state and `solver_ok`."""
    state = EnvState(y=y, steps=jnp.zeros((), dtype=int))
    next_state, info = env.transition(state, action, key=None)
    return next_state.y, info["solver_ok"]


def closed_loop_step(env: AbstractEnv, kind: str, theta: Array) -> Callable[[Array, Any], Array]:
    """`(y, k) -> y_{k+1}`: one env step under policy `kind` with parameters `theta`, no termination."""

    def step(y, k):
        action = policy_action(kind, theta, y, k)
        return step_state(env, y, jnp.reshape(action, env.action_space.shape))[0]

    return step


def _stage_costs(env, y0, kind, steps, state_weight, action_weight, theta, horizon):
    def advance(y, action):
        next_y, step_ok = step_state(env, y, jnp.reshape(action, env.action_space.shape))
        cost = env.dt * (state_weight * jnp.sum(next_y**2) + action_weight * jnp.sum(action**2))
        return next_y, step_ok, cost

    def hold(y, action):
        return y, jnp.asarray(True), jnp.zeros((), dtype=y.dtype)

    def body(carry, k):
        y, ok = carry
        action = policy_action(kind, theta, y, k)
        next_y, step_ok, cost = jax.lax.cond(k < horizon, advance, hold, y, action)
        return (next_y, ok & step_ok), cost

    (_, ok), values = jax.lax.scan(body, (y0, jnp.asarray(True)), jnp.arange(steps))
    return values, ok


def stage_costs(
    env: AbstractEnv, y0: Array, kind: str, steps: int, state_weight: float, action_weight: float
) -> Callable[[Array, Any], tuple[Float[Array, " steps"], BoolScalar]]:
    """`(theta, horizon) -> ((c_0, ..., c_{steps-1}), all solves ok)`: the cost of each step.

    `c_k = dt (state_weight |y_{k+1}|^2 + action_weight |a_k|^2)` for `k < horizon` and 0
    after, so `f = sum_k c_k` is the cost over `horizon` steps. The rollout goes through
    `env.transition`, the scene's physical input and solver, without termination or reset
    (the cost is as smooth as the dynamics). `horizon` (at most `steps`) may be traced:
    one compilation serves every horizon. Past it the steps are skipped (`lax.cond` on a
    predicate that `vmap` over `theta` leaves unbatched, so the skip is real): they cost
    nothing, cannot fail, and feed nothing into the gradient.

    The function is a `jax.tree_util.Partial`, a pytree whose leaves are the env's arrays and
    `y0`: given to a program as an argument (`eqx.filter_jit`: `lerax_like.gradients.Evaluators`),
    one compilation serves every start and env of the same structure.
    """
    return Partial(_stage_costs, env, jnp.asarray(y0), kind, int(steps), float(state_weight), float(action_weight))


def _summed(costs, theta, horizon):
    values, ok = costs(theta, horizon)
    return jnp.sum(values), ok


def objective(costs):
    """`(theta, horizon) -> (f, all solves ok)`: the summed `stage_costs` (a `Partial` too, its
    leaves theirs)."""
    return Partial(_summed, costs)


def active_parameters(kind: str, theta: Array, horizon: int) -> np.ndarray:
    """Which entries of `theta` (flattened) act within `horizon` steps: the first `horizon`
    actions of an open-loop sequence, the whole gain of a feedback policy."""
    active = np.ones(theta.shape, dtype=bool)
    if kind == "open_loop":
        active[horizon:] = False
    return active.reshape(-1)


def nominal_parameters(env: AbstractEnv, kind: str, horizon: int, gain: Array) -> Array:
    """The `theta` the study smooths around: zero actions, or the nominal feedback gain."""
    if kind == "open_loop":
        return jnp.zeros((horizon, action_size(env)), dtype=env.dt.dtype)
    return gain.astype(env.dt.dtype)


def lqr_gain(env: AbstractEnv, state_weight: float, action_weight: float, iterations: int = 5000) -> np.ndarray:
    """The gain `G` of `a = G y` (so `G = -K`) of the discrete LQR at the origin, by Riccati iteration.

    The env step is linearised at `y = 0`, `a = 0` (the upright equilibrium of the
    cart-poles); the weights are the study cost's, `Q = state_weight dt I`, `R =
    action_weight dt I`.
    """
    n = env.initial(key=jr.key(0)).y.shape[0]
    m = action_size(env)
    dtype = env.dt.dtype
    y = jnp.zeros((n,), dtype)
    a = jnp.zeros((m,), dtype)
    step = lambda y, a: step_state(env, y, jnp.reshape(a, env.action_space.shape))[0]  # noqa: E731
    # Reverse mode: an adaptive solve's default adjoint is a custom VJP, which forward mode cannot pass.
    A = np.asarray(jax.jacrev(step, argnums=0)(y, a), dtype=np.float64)
    B = np.asarray(jax.jacrev(step, argnums=1)(y, a), dtype=np.float64)
    dt = float(env.dt)
    Q = state_weight * dt * np.eye(n) + 1e-12 * np.eye(n)
    R = max(action_weight, 1e-12) * dt * np.eye(m)
    P = Q.copy()
    for _ in range(iterations):
        K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
        P_next = Q + A.T @ P @ (A - B @ K)
        if np.allclose(P_next, P, rtol=1e-12, atol=0):
            P = P_next
            break
        P = P_next
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    return -K


def nominal_gain(env64: AbstractEnv, feedback_gain: str, state_weight: float, action_weight: float) -> np.ndarray:
    """The feedback gain the linear policy smooths around: the LQR gain of `env64` (the
    study's env in float64) for the cost's weights (`feedback_gain="lqr"`), or zero (`"zero"`)."""
    if feedback_gain == "lqr":
        return lqr_gain(env64, state_weight, action_weight)
    return np.zeros((action_size(env64), env64.initial(key=jr.key(0)).y.shape[0]))
