"""Reference trajectories computed independently of diffrax, with SciPy's `solve_ivp`.

The env holds each input constant over one env step and integrates each step afresh, the
vector field read at the episode's time `k dt + s` at `s` into step `k`, so the reference
does exactly that: one `solve_ivp` call per env step over `[0, dt]`, the field read at
`k dt + s`, restarted at the step boundaries where the input jumps. Integrating across a
jump would cost the reference its order at every boundary.

The vector field is the dynamics' own `vector_field`, compiled with `jax.jit` and called
from NumPy in float64. A batch of initial states is integrated as one stacked system, so
that each SciPy step costs one compiled call for the whole batch: the Python overhead per
call, not the arithmetic, is what a tight-tolerance SciPy solve pays for.
"""

from typing import Any

import numpy as np


def scipy_solve_ivp():
    """SciPy's `solve_ivp`, or an ImportError with the install hint."""
    try:
        from scipy.integrate import solve_ivp
    except ImportError as error:  # pragma: no cover - depends on the environment
        raise ImportError(
            "the reference solutions need SciPy: pip install 'lerax_like[study]'"
        ) from error
    return solve_ivp


IMPLICIT_METHODS = ("Radau", "BDF", "LSODA")


def reference_trajectories(
    dynamics,
    y0s: np.ndarray,
    inputs: np.ndarray,
    dt: float,
    *,
    method: str = "DOP853",
    rtol: float = 1e-13,
    atol: float = 1e-13,
) -> np.ndarray:
    """States after each env step for each initial state, shape `(B, T, n)`.

    - `dynamics`: the physics module; its `vector_field(t, y, u)` is integrated.
    - `y0s`: initial states, shape `(B, n)`.
    - `inputs`: physical inputs, shape `(T, m)`; `inputs[k]` is held over env step `k`,
      the same for every initial state.
    - `method`, `rtol`, `atol`: passed to `scipy.integrate.solve_ivp`. The implicit
      methods get the exact Jacobian (`jax.jacfwd` of the vector field).

    Everything is float64, whatever the dtype of the study.
    """
    return _solve(dynamics, y0s, inputs, dt, method=method, rtol=rtol, atol=atol, fractions=None)[0]


def dense_reference_trajectories(
    dynamics,
    y0s: np.ndarray,
    inputs: np.ndarray,
    dt: float,
    fractions: np.ndarray,
    *,
    method: str = "DOP853",
    rtol: float = 1e-13,
    atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """As `reference_trajectories`, and the states inside each env step from SciPy's dense output.

    `fractions`, in `(0, 1)`: the times `k dt + fractions[j] dt` inside env step `k`
    where the reference is evaluated, by the method's own continuous extension
    (`solve_ivp(..., dense_output=True)`, from the same solve). Returns the states after
    each env step, shape `(B, T, n)`, and inside, shape `(B, T, len(fractions), n)`.
    """
    fractions = np.asarray(fractions, dtype=np.float64)
    if fractions.ndim != 1 or np.any(fractions <= 0) or np.any(fractions >= 1):
        raise ValueError(f"fractions must be a 1-d array of values in (0, 1), got {fractions}")
    return _solve(dynamics, y0s, inputs, dt, method=method, rtol=rtol, atol=atol, fractions=fractions)


def _solve(dynamics, y0s, inputs, dt, *, method, rtol, atol, fractions):
    import jax
    import jax.numpy as jnp

    solve_ivp = scipy_solve_ivp()
    y0s = np.asarray(y0s, dtype=np.float64)
    batch, size = y0s.shape
    inputs = np.asarray(inputs, dtype=np.float64)
    dense = fractions is not None

    with jax.enable_x64(True):
        # The reference is float64 whatever the study's dtype.
        dynamics = jax.tree.map(lambda leaf: jnp.asarray(leaf, dtype=jnp.float64), dynamics)

        def stacked(t, flat_y, u):
            ys = jnp.reshape(flat_y, (batch, size))
            return jnp.reshape(jax.vmap(lambda y: dynamics.vector_field(t, y, u))(ys), (-1,))

        vector_field = jax.jit(stacked)
        jacobian = jax.jit(jax.jacfwd(stacked, argnums=1))

        # `t0 + s` in float64, as the env's `EpisodeTime` reads it.
        def f(s, y, u, t0):
            return np.asarray(vector_field(np.float64(t0 + s), y, u))

        def jac(s, y, u, t0):
            return np.asarray(jacobian(np.float64(t0 + s), y, u))

        options: dict[str, Any] = {"jac": jac} if method in IMPLICIT_METHODS else {}
        y = np.reshape(y0s, (-1,))
        states = np.empty((len(inputs), batch * size), dtype=np.float64)
        inside = np.empty((len(inputs), len(fractions) if dense else 0, batch * size), dtype=np.float64)
        for k, u in enumerate(inputs):
            t0 = np.float64(k) * np.float64(dt)
            solution = solve_ivp(
                f, (0.0, float(dt)), y, method=method, rtol=rtol, atol=atol, args=(u, t0), dense_output=dense, **options
            )
            if not solution.success:
                raise RuntimeError(f"reference solve ({method}) failed at env step {k}: {solution.message}")
            y = solution.y[:, -1]
            states[k] = y
            if dense:
                inside[k] = solution.sol(fractions * float(dt)).T
    states = np.transpose(np.reshape(states, (len(inputs), batch, size)), (1, 0, 2))
    inside = np.transpose(np.reshape(inside, (len(inputs), inside.shape[1], batch, size)), (2, 0, 1, 3))
    return states, inside
