"""Checking autodiff gradients against central finite differences, leaf by leaf (`gradcheck`).

Finite differences are only a reference where the function is smooth around the point:
at a termination threshold, an action clip or a jump in an adaptive solver's number of
steps they measure a different quantity (or nothing at all). The report is then the
evidence of that, not a failure of autodiff.
"""

import dataclasses
from collections.abc import Callable
from typing import Any, Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree


@dataclasses.dataclass(frozen=True)
class LeafCheck:
    """The check of one differentiated leaf.

    - `path`: where the leaf is in the tree (`jax.tree_util.keystr`).
    - `autodiff`, `finite_difference`: the two gradients, shaped like the leaf.
    - `step`: the finite-difference step used for each element.
    - `relative_error`: `|autodiff - finite_difference| / max(|finite_difference|, |autodiff|, floor)`
      in the 2-norm over the leaf's elements.
    """

    path: str
    autodiff: np.ndarray
    finite_difference: np.ndarray
    step: np.ndarray
    relative_error: float


@dataclasses.dataclass(frozen=True)
class GradCheckReport:
    """Per-leaf results of `gradcheck`; `str(report)` is a table."""

    value: float
    leaves: tuple[LeafCheck, ...]
    mode: str

    @property
    def max_relative_error(self) -> float:
        return max((leaf.relative_error for leaf in self.leaves), default=0.0)

    def passed(self, rtol: float) -> bool:
        """Whether every leaf's relative error is at most `rtol`."""
        return self.max_relative_error <= rtol

    def __getitem__(self, path: str) -> LeafCheck:
        for leaf in self.leaves:
            if leaf.path == path:
                return leaf
        raise KeyError(f"no leaf {path!r}; leaves are {[leaf.path for leaf in self.leaves]}")

    def __str__(self) -> str:
        rows = [f"gradcheck ({self.mode} mode), f = {self.value:.10g}"]
        width = max((len(leaf.path) for leaf in self.leaves), default=4)
        rows.append(f"{'leaf':<{width}}  {'autodiff':>14}  {'finite diff':>14}  {'rel. error':>10}  {'step':>8}")
        for leaf in self.leaves:
            ad = leaf.autodiff.ravel()
            fd = leaf.finite_difference.ravel()
            for i in range(ad.size):
                name = leaf.path if i == 0 else ""
                error = f"{leaf.relative_error:10.2e}" if i == 0 else ""
                suffix = f"[{i}]" if ad.size > 1 else ""
                rows.append(
                    f"{name + suffix:<{width}}  {ad[i]:>14.7g}  {fd[i]:>14.7g}  {error:>10}  {leaf.step.ravel()[i]:>8.1e}"
                )
        return "\n".join(rows)

    __repr__ = __str__


def selection_spec(tree, where):
    """A filter spec: True on the inexact array leaves of `where(tree)` (all of `tree` if None)."""
    if where is None:
        return jax.tree.map(eqx.is_inexact_array, tree)
    spec = jax.tree.map(lambda _: False, tree)
    selected = jax.tree.map(eqx.is_inexact_array, where(tree))
    return eqx.tree_at(where, spec, selected)


def gradcheck(
    fn: Callable[[Any], Any],
    tree: Any,
    *,
    where: Callable[[Any], Any] | None = None,
    mode: Literal["reverse", "forward"] = "reverse",
    relative_step: float = 6e-6,
    floor: float = 1e-12,
    batched: bool = True,
) -> GradCheckReport:
    """Compare the gradient of the scalar `fn(tree)` with central finite differences.

    **Arguments:**

    - `fn`: a function of `tree` returning a scalar; pure and jittable.
    - `tree`: any pytree (an env, a dict of arrays). Its floating-point array leaves are
      differentiated, or those under `where(tree)` if `where` is given (e.g.
      `where=lambda env: (env.dynamics, env.dt)`).
    - `mode`: `"reverse"` (`jax.grad`) or `"forward"` (`jax.jacfwd`; an env needs the
      `"forward"` adjoint for it, see `lerax_like.with_adjoint`).
    - `relative_step`: the step for an element `x` is `relative_step * |x|` (or
      `relative_step` where `x == 0`); float64's `eps**(1/3)` (6e-6) balances truncation
      (`h**2`) and rounding (`eps / h`) of central differences, which run in float64.
    - `floor`: the smallest denominator of the relative error, so that a gradient that is
      zero on both sides reads as agreement rather than 0/0.
    - `batched`: evaluate the perturbed functions with one `jax.vmap` (one compilation)
      rather than one by one.

    Finite differences are computed in float64; call it with `jax_enable_x64` on.
    """
    if not jax.config.read("jax_enable_x64"):
        # In float32 a central difference's rounding, eps / h relative, is 2e-5 at the best step
        # h = eps**(1/3) and far more for a function that cancels: a check would measure that noise.
        raise RuntimeError(
            "gradcheck needs float64: in float32 finite differences carry rounding noise of 2e-5 relative or "
            "more, so a comparison with autodiff would measure that noise. Set "
            "jax.config.update('jax_enable_x64', True) at the start of the script (or run it inside "
            "`with jax.enable_x64(True):`)."
        )
    if mode not in ("reverse", "forward"):
        raise ValueError(f"mode must be 'reverse' or 'forward', got {mode!r}")
    params, static = eqx.partition(tree, selection_spec(tree, where))
    flat, unravel = ravel_pytree(params)
    if flat.size == 0:
        raise ValueError("nothing to differentiate: no floating-point array leaves selected")
    flat = flat.astype(jnp.float64)

    def flat_fn(v):
        value = fn(eqx.combine(unravel(v), static))
        return jnp.asarray(value, dtype=jnp.float64).reshape(())

    differentiate = jax.grad if mode == "reverse" else jax.jacfwd
    autodiff = jax.jit(differentiate(flat_fn))(flat)

    # Relative steps: `dt = 0.02` needs a step far below 1e-5 for an O(h**2) error of 1e-10.
    step = relative_step * jnp.where(flat == 0, 1.0, jnp.abs(flat))
    # Make x + h exactly representable, so that the step taken is the step divided by.
    step = (flat + step) - flat
    perturbations = jnp.diag(step)
    points = jnp.concatenate([flat[None], flat + perturbations, flat - perturbations])
    if batched:
        values = jax.jit(jax.vmap(flat_fn))(points)
    else:
        jitted = jax.jit(flat_fn)
        values = jnp.stack([jitted(p) for p in points])
    value = float(values[0])
    plus, minus = values[1 : flat.size + 1], values[flat.size + 1 :]
    finite_difference = (plus - minus) / (2 * step)

    autodiff, finite_difference, step = (np.asarray(a) for a in (autodiff, finite_difference, step))
    leaves_with_paths = jax.tree_util.tree_flatten_with_path(params)[0]
    checks = []
    start = 0
    for path, leaf in leaves_with_paths:
        stop = start + leaf.size
        ad, fd = autodiff[start:stop], finite_difference[start:stop]
        scale = max(np.linalg.norm(fd), np.linalg.norm(ad), floor)
        checks.append(
            LeafCheck(
                path=jax.tree_util.keystr(path),
                autodiff=ad.reshape(leaf.shape),
                finite_difference=fd.reshape(leaf.shape),
                step=step[start:stop].reshape(leaf.shape),
                relative_error=float(np.linalg.norm(ad - fd) / scale),
            )
        )
        start = stop
    return GradCheckReport(value=value, leaves=tuple(checks), mode=mode)
