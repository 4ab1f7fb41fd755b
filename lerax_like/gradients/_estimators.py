"""Estimators of the gradient of a Gaussian-smoothed objective, and the reference they are judged by.

`F(theta) = E_w f(theta + sigma w)`: the first-order estimator (through the simulator's
derivative), the zeroth-order one (black box), their variance-minimising interpolation
(Suh et al., 2022), and an antithetic zeroth-order reference that is unbiased by Stein's
lemma and never uses the simulator's derivative. The study that uses them is
`lerax_like.analysis.gradient_variance`.
"""

import math
import time
from collections.abc import Callable
from typing import Any, final

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from .._types import Array, BoolScalar, Scalar


ESTIMATORS: tuple[str, ...] = ("first_order", "zeroth_order", "alpha_order")


def per_sample_statistics(estimates: np.ndarray) -> dict[str, float]:
    """Norm, variance (trace of the covariance) and their standard errors of per-sample estimates."""
    n = estimates.shape[0]
    mean = estimates.mean(axis=0)
    squared = np.sum((estimates - mean) ** 2, axis=1)
    variance = float(squared.sum() / (n - 1))
    return {
        "mean": mean,
        "gradient_norm": float(np.linalg.norm(mean)),
        "gradient_norm_standard_error": math.sqrt(variance / n),
        "variance": variance,
        "variance_standard_error": float(np.std(squared, ddof=1) / math.sqrt(n)),
        "samples": int(n),
    }


def alpha_weight(first: np.ndarray, zeroth: np.ndarray) -> tuple[float, bool]:
    """The weight of the first-order part that minimises the variance of the interpolation,
    and whether the guard set it to 0.

    With `V1`, `V0` the traces of the two per-sample covariances and `C` of their
    cross-covariance (the samples are paired), `alpha = (V0 - C) / (V1 + V0 - 2C)` in
    `[0, 1]`. The guard (Suh et al., 2022): when the two means differ by more than three
    standard errors of their difference, the first-order estimate is taken to be biased
    and `alpha = 0`.
    """
    n = first.shape[0]
    d1 = first - first.mean(axis=0)
    d0 = zeroth - zeroth.mean(axis=0)
    v1 = np.sum(d1**2) / (n - 1)
    v0 = np.sum(d0**2) / (n - 1)
    c = np.sum(d1 * d0) / (n - 1)
    difference = first - zeroth
    spread = np.sum((difference - difference.mean(axis=0)) ** 2) / (n - 1)
    if np.linalg.norm(difference.mean(axis=0)) > 3 * math.sqrt(spread / n):
        return 0.0, True
    denominator = v1 + v0 - 2 * c
    alpha = 1.0 if denominator <= 0 else float(np.clip((v0 - c) / denominator, 0.0, 1.0))
    return alpha, False


def _values(f, thetas, horizon):
    return jax.vmap(f, in_axes=(0, None))(thetas, horizon)


def _gradients(f, thetas, horizon):
    return jax.vmap(jax.value_and_grad(f, has_aux=True), in_axes=(0, None))(thetas, horizon)


# `f` is an argument, not a constant of the program: an `f` that is a pytree (the study's objective,
# a `jax.tree_util.Partial`) passes its arrays (the env's parameters, the start) as the program's
# inputs, so that another objective of the same structure (another start, other parameters) runs
# the same program, traced and compiled once.
_PROGRAMS = {"values": eqx.filter_jit(_values), "gradients": eqx.filter_jit(_gradients)}


@final
class Evaluators:
    """`f` and `(f, grad f)` over a batch of `theta` at one `horizon`, compiled once for
    every horizon up to the objective's `steps` (the horizon is traced), and once for every
    `f` of the same structure when `f` is a pytree of arrays (a `jax.tree_util.Partial`, an
    Equinox module: its arrays are the programs' inputs, not constants)."""

    def __init__(self, f):
        self.f = f
        self._compiled: dict[str, Any] = {}
        self.compile_seconds = 0.0

    def __call__(self, which: str, thetas: Array, horizon):
        horizon = jnp.asarray(horizon, dtype=int)
        if which not in self._compiled:
            start = time.perf_counter()
            self._compiled[which] = _PROGRAMS[which].lower(self.f, thetas, horizon).compile()
            self.compile_seconds += time.perf_counter() - start
        return self._compiled[which](self.f, thetas, horizon)


def estimate_gradients(
    f: Callable[[Array, Any], tuple[Scalar, BoolScalar]],
    theta: Array,
    active: np.ndarray,
    horizon: int,
    sigma: float,
    *,
    samples: int,
    reference_samples: int,
    key,
    evaluators: Evaluators | None = None,
) -> dict[str, Any]:
    """The three estimators of `grad F` at `theta` over `samples` draws, and the reference.

    `f(theta, horizon)` is the objective, `active` (flattened `theta`'s shape) marks the
    entries that act within `horizon`: only those are perturbed and estimated. Returns
    `{"first_order", "zeroth_order", "alpha_order", "reference"}`, each a dict of
    `per_sample_statistics` (`mean` is the estimate over the active entries) and
    `failed_samples`, and for `alpha_order` its `alpha` and whether the guard set it. The
    zeroth-order estimator uses the values `f(theta + sigma w)` that the first-order
    evaluation returns beside the gradients, at the same draws.
    """
    evaluators = evaluators or Evaluators(f)
    dtype = theta.dtype
    estimator_key, reference_key = jr.split(key)
    mask = jnp.asarray(active.reshape(theta.shape), dtype=dtype)
    sigma_ = jnp.asarray(sigma, dtype=dtype)

    def draw(draw_key):
        return jr.normal(draw_key, (samples, *theta.shape), dtype=dtype) * mask

    def flat(x):
        return np.asarray(x, dtype=np.float64).reshape(x.shape[0], -1)[:, active]

    # At the compiled batch size, which the reference reuses: one compilation.
    f0, ok0 = evaluators("values", jnp.broadcast_to(theta, (samples, *theta.shape)), horizon)
    if not bool(ok0[0]):
        raise RuntimeError("the solve of the nominal rollout failed; check the solver and the scene's settings")
    f0 = float(f0[0])

    noise = draw(estimator_key)
    (values, ok), gradients = evaluators("gradients", theta + sigma_ * noise, horizon)
    ok = np.asarray(ok, dtype=bool)
    first = flat(gradients)[ok]
    zeroth = ((np.asarray(values, dtype=np.float64) - f0)[:, None] * flat(noise) / sigma)[ok]
    failed = int(np.sum(~ok))
    if first.shape[0] < 2:
        raise RuntimeError(f"{failed} of {samples} sample solves failed; too few left for a variance")

    # The reference: antithetic zeroth order, in batches of the compiled size.
    reference_estimates = []
    reference_failed = 0
    for batch_key in jr.split(reference_key, reference_samples // samples):
        w = draw(batch_key)
        plus, ok_plus = evaluators("values", theta + sigma_ * w, horizon)
        minus, ok_minus = evaluators("values", theta - sigma_ * w, horizon)
        good = np.asarray(ok_plus & ok_minus, dtype=bool)
        reference_failed += int(np.sum(~good))
        difference = (np.asarray(plus, dtype=np.float64) - np.asarray(minus, dtype=np.float64))[:, None]
        reference_estimates.append((difference * flat(w) / (2 * sigma))[good])
    reference = np.concatenate(reference_estimates)

    alpha, guarded = alpha_weight(first, zeroth)
    results = {
        "first_order": per_sample_statistics(first),
        "zeroth_order": per_sample_statistics(zeroth),
        "alpha_order": {**per_sample_statistics(alpha * first + (1 - alpha) * zeroth), "alpha": alpha, "guarded": guarded},
        "reference": {**per_sample_statistics(reference), "failed_samples": reference_failed},
    }
    for name in ESTIMATORS:
        results[name]["failed_samples"] = failed
    return results
