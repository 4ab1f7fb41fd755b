"""Sensitivities along a trajectory: `d y(t_k) / d p` of the env's solver against a tight reference.

The env's gradient (under `"checkpoint"` or `"forward"`) is the exact derivative of the
*discrete* solution; the continuous system's differs from it by an error of the order of
the solver's, which can flip a sensitivity's sign. `sensitivity_signs` finds where, against
`reference_integrator` (Dopri8 at tight tolerances), the stand-in for the continuous system.
"""

import math
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import diffrax
import numpy as np

from .._types import Array, Float, State
from ..env import AbstractEnv, EnvState, rollout
from ..integrate import Integrator, make_integrator, with_adjoint


def with_integrator(env: AbstractEnv, integrator: Integrator) -> AbstractEnv:
    """`env` with its integrator replaced."""
    return eqx.tree_at(lambda e: e.integrator, env, integrator)


def reference_integrator(rtol: float = 1e-12, dtmax: float = math.inf) -> Integrator:
    """Dopri8 at tight tolerances (`atol = rtol / 100`): the stand-in for the continuous system."""

    # Tolerances and largest step as arrays, not Python floats or None: they are then
    # traced leaves, and the reference and its floor estimate share one compilation.
    relative = jnp.asarray(rtol)
    controller = diffrax.PIDController(rtol=relative, atol=relative * 1e-2, dtmax=jnp.asarray(dtmax))
    return make_integrator("dopri8", controller, max_steps=100_000)


def trajectory_sensitivity(
    env: AbstractEnv, where: Callable[[AbstractEnv], Array], y0: State, actions: Array
) -> Float[Array, "T n"]:
    """`d ys / d where(env)` along a rollout, shape `(T, n)`, by forward mode (one pass).

    `where(env)` must be a scalar leaf; the env's integrator gets the forward adjoint.
    """

    env = with_adjoint(env, "forward")

    def ys(parameter):
        perturbed = eqx.tree_at(where, env, parameter)
        state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
        return rollout(perturbed, state, actions, key=jr.key(0))[0]

    return eqx.filter_jit(jax.jacfwd(ys))(where(env))


def sensitivity_signs(
    env: AbstractEnv,
    where: Callable[[AbstractEnv], Array],
    y0: State,
    actions: Array,
    component: int,
    *,
    reference_rtol: float = 1e-12,
    threshold: float = 0.2,
) -> dict[str, Any]:
    """Where the env's own solver gets the sign of `d y_component(t_k) / d where(env)` wrong.

    Compares the sensitivity along the rollout of `actions` from `y0` (one value per env
    step, by `trajectory_sensitivity`) with the reference's (`reference_integrator`).
    Returns `{"times", "sensitivity", "reference", "wrong_sign_fraction",
    "first_clear_wrong_sign_step"}`: the last is the first step at which the signs
    differ while both magnitudes exceed `threshold` times the reference's largest (a
    disagreement that is no near-zero crossing), or None.
    """
    approximate = np.asarray(trajectory_sensitivity(env, where, y0, actions)[:, component])
    exact_env = with_integrator(env, reference_integrator(reference_rtol))
    exact = np.asarray(trajectory_sensitivity(exact_env, where, y0, actions)[:, component])
    wrong = np.sign(approximate) != np.sign(exact)
    large = np.minimum(np.abs(approximate), np.abs(exact)) > threshold * np.max(np.abs(exact))
    clear = np.nonzero(wrong & large)[0]
    return {
        "times": (float(env.dt) * np.arange(1, len(exact) + 1)).tolist(),
        "sensitivity": approximate.tolist(),
        "reference": exact.tolist(),
        "wrong_sign_fraction": float(np.mean(wrong)),
        "first_clear_wrong_sign_step": int(clear[0]) if clear.size else None,
        "threshold": threshold,
    }
