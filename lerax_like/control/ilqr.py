"""Iterative LQR (Li and Todorov, 2004) for a discrete-time model `y' = step(y, a)`.

Dynamics are linearised by forward-mode autodiff, costs expanded to second order by
autodiff; the backward pass is a `lax.scan`; the forward pass tries several step
lengths at once (`vmap`) and keeps the cheapest. Actions are clipped to `[low, high]` in
the forward pass (a clipped, not box-constrained, iLQR). Fixed iteration count, so the
whole solve is one compiled function.
"""

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._types import Array, Float, Scalar


def trajectory_cost(step, stage_cost, terminal_cost, y0, actions):
    def body(y, a):
        return step(y, a), stage_cost(y, a)

    y_final, costs = jax.lax.scan(body, y0, actions)
    return jnp.sum(costs) + terminal_cost(y_final)


def ilqr(
    step: Callable[[Array, Array], Array],
    stage_cost: Callable[[Array, Array], Scalar],
    terminal_cost: Callable[[Array], Scalar],
    y0: Float[Array, " n"],
    actions: Float[Array, "T m"],
    *,
    iterations: int = 10,
    regularisation: float = 1e-3,
    low: float = -1.0,
    high: float = 1.0,
    step_lengths: tuple[float, ...] = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01),
) -> tuple[Float[Array, "T m"], Scalar]:
    """Locally optimal actions from `actions` (the warm start), and their cost."""
    n_actions = actions.shape[1]
    alphas = jnp.asarray(step_lengths, dtype=y0.dtype)

    def rollout_states(actions):
        def body(y, a):
            y_next = step(y, a)
            return y_next, y

        y_final, ys = jax.lax.scan(body, y0, actions)
        return ys, y_final

    def iteration(_, carry):
        actions, current_cost = carry
        ys, y_final = rollout_states(actions)
        A, B = jax.vmap(jax.jacfwd(step, argnums=(0, 1)))(ys, actions)
        l_x, l_u = jax.vmap(jax.grad(stage_cost, argnums=(0, 1)))(ys, actions)
        (l_xx, l_xu), (_, l_uu) = jax.vmap(jax.hessian(stage_cost, argnums=(0, 1)))(ys, actions)
        V_x = jax.grad(terminal_cost)(y_final)
        V_xx = jax.hessian(terminal_cost)(y_final)

        def backward(value, inputs):
            V_x, V_xx = value
            A, B, l_x, l_u, l_xx, l_xu, l_uu = inputs
            Q_x = l_x + A.T @ V_x
            Q_u = l_u + B.T @ V_x
            Q_xx = l_xx + A.T @ V_xx @ A
            Q_uu = l_uu + B.T @ V_xx @ B + regularisation * jnp.eye(n_actions, dtype=y0.dtype)
            Q_ux = l_xu.T + B.T @ V_xx @ A
            k = -jnp.linalg.solve(Q_uu, Q_u)
            K = -jnp.linalg.solve(Q_uu, Q_ux)
            V_x = Q_x + K.T @ Q_uu @ k + K.T @ Q_u + Q_ux.T @ k
            V_xx = Q_xx + K.T @ Q_uu @ K + K.T @ Q_ux + Q_ux.T @ K
            return (V_x, (V_xx + V_xx.T) / 2), (k, K)

        _, (ks, Ks) = jax.lax.scan(
            backward, (V_x, V_xx), (A, B, l_x, l_u, l_xx, l_xu, l_uu), reverse=True
        )

        def forward(alpha):
            def body(y, inputs):
                a, y_reference, k, K = inputs
                a_new = jnp.clip(a + alpha * k + K @ (y - y_reference), low, high)
                return step(y, a_new), (a_new, stage_cost(y, a_new))

            y_final, (new_actions, costs) = jax.lax.scan(body, y0, (actions, ys, ks, Ks))
            return new_actions, jnp.sum(costs) + terminal_cost(y_final)

        candidates, costs = jax.vmap(forward)(alphas)
        costs = jnp.where(jnp.isfinite(costs), costs, jnp.inf)
        best = jnp.argmin(costs)
        improved = costs[best] < current_cost
        actions = jnp.where(improved, candidates[best], actions)
        return actions, jnp.where(improved, costs[best], current_cost)

    actions = jnp.clip(actions, low, high)
    return jax.lax.fori_loop(
        0, iterations, iteration, (actions, trajectory_cost(step, stage_cost, terminal_cost, y0, actions))
    )
