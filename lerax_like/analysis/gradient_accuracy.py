"""Gradient accuracy: how far the gradient of the discretised env is from the continuous system's.

An env's gradient (with the default `RecursiveCheckpointAdjoint`) is the exact derivative
of the *discrete* solution. That is what an optimiser of the env sees, but when the env
stands for a physical system, the quantity of interest is the derivative of the
continuous system: they differ by an error that shrinks with the solver's step like the
solver's own error, and it can flip a gradient's sign. `gradient_work_precision`
measures this error against a tight reference, beside the run time of the gradient:
the work-precision idea applied to gradients.
"""

import time
from collections.abc import Callable, Sequence
from typing import Any

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax.flatten_util import ravel_pytree

from .._types import Array
from ..env import AbstractEnv, EnvState, rollout
from ..gradients import with_adjoint
from ..integrate import Integrator, make_integrator
from .gradcheck import _selection


def with_integrator(env: AbstractEnv, integrator: Integrator) -> AbstractEnv:
    """`env` with its integrator replaced."""
    return eqx.tree_at(lambda e: e.integrator, env, integrator)


def reference_integrator(rtol: float = 1e-12) -> Integrator:
    """Dopri8 at tight tolerances: the stand-in for the continuous system."""
    return make_integrator(
        "dopri8", diffrax.PIDController(rtol=rtol, atol=rtol * 1e-2), max_steps=100_000
    )


def trajectory_sensitivity(
    env: AbstractEnv, where: Callable[[AbstractEnv], Array], y0: Array, actions: Array
) -> Array:
    """`d ys / d where(env)` along a rollout, shape `(T, n)`, by forward mode (one pass).

    `where(env)` must be a scalar leaf; the env's integrator gets the forward adjoint.
    """
    env = with_adjoint(env, "forward")

    def ys(parameter):
        perturbed = eqx.tree_at(where, env, parameter)
        state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
        return rollout(perturbed, state, actions, key=jr.key(0))[0]

    return eqx.filter_jit(jax.jacfwd(ys))(where(env))


def _timed(fn, *args, repeats: int = 5) -> float:
    jax.block_until_ready(fn(*args))  # compile first
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def gradient_work_precision(
    env: AbstractEnv,
    loss: Callable[[AbstractEnv], Array],
    where: Callable[[AbstractEnv], Any],
    integrators: Sequence[tuple[str, Integrator]],
    *,
    reference: Integrator | None = None,
    repeats: int = 5,
) -> list[dict[str, Any]]:
    """Error and run time of `grad(loss)` with respect to `where(env)`, per integrator.

    The error is `|g - g_ref| / |g_ref|` (2-norm over all selected leaves) with `g_ref`
    computed with `reference` (default `reference_integrator()`). Returns one row per
    integrator: `{"label", "steps_per_env_step", "rtol", "error", "seconds", "gradient"}`.
    """
    reference = reference_integrator() if reference is None else reference

    def gradient_with(integrator):
        env_i = with_integrator(env, integrator)
        params, static = eqx.partition(env_i, _selection(env_i, where))
        fn = eqx.filter_jit(jax.grad(lambda p: loss(eqx.combine(p, static))))
        return fn, params

    fn, params = gradient_with(reference)
    g_ref, _ = ravel_pytree(fn(params))
    rows = []
    for label, integrator in integrators:
        fn, params = gradient_with(integrator)
        g, _ = ravel_pytree(fn(params))
        rows.append(
            {
                "label": label,
                "steps_per_env_step": integrator.substeps,
                "rtol": float(getattr(integrator.stepsize_controller, "rtol", float("nan"))),
                "error": float(jnp.linalg.norm(g - g_ref) / jnp.linalg.norm(g_ref)),
                "seconds": _timed(fn, params, repeats=repeats),
                "gradient": np.asarray(g).tolist(),
            }
        )
    rows.append({"label": "reference", "gradient": np.asarray(g_ref).tolist()})
    return rows

