"""Finite-time Lyapunov exponents of a step map: how fast a rollout's gradient can grow."""

from collections.abc import Callable

import jax
import jax.numpy as jnp

from .._types import Array, Float, IntScalar, ScalarLike, State


def finite_time_lyapunov(
    step: Callable[[State, IntScalar], State], y0: State, horizon: int, dt: ScalarLike
) -> Float[Array, "H n"]:
    """Finite-time Lyapunov exponents (1/s) of the step map `y_{k+1} = step(y_k, k)` along the
    trajectory from `y0`, after each of `horizon` steps of `dt` seconds: row `k` holds the
    `n` exponents over `k + 1` steps.

    The tangent map `J_k = d y_{k+1} / d y_k` (a policy's feedback included, when `step`
    closes the loop) is propagated with QR renormalisation (Benettin et al., 1980):
    `J_k Q_k = Q_{k+1} R_{k+1}`, and the exponents are the running sums of `log |diag R|`
    over elapsed time. `step` must be differentiable in `y` by reverse mode and jittable.
    """
    n = y0.shape[0]

    def body(carry, k):
        y, Q, logs = carry
        J = jax.jacrev(step)(y, k)  # reverse: forward mode cannot pass an adaptive solve's custom VJP
        Q, R = jnp.linalg.qr(J @ Q)
        signs = jnp.sign(jnp.diag(R))
        Q = Q * jnp.where(signs == 0, 1.0, signs)
        logs = logs + jnp.log(jnp.abs(jnp.diag(R)))
        return (step(y, k), Q, logs), logs

    eye = jnp.eye(n, dtype=y0.dtype)
    _, logs = jax.jit(lambda: jax.lax.scan(body, (y0, eye, jnp.zeros((n,), y0.dtype)), jnp.arange(horizon)))()
    elapsed = dt * jnp.arange(1, horizon + 1, dtype=y0.dtype)
    return logs / elapsed[:, None]
