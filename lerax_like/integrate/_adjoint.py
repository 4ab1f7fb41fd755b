"""Choosing how gradients pass through the solves of an env: the adjoint.

Every env step is a `diffrax.diffeqsolve`, so the adjoint is a property of the env's
`Integrator`. The three of `ADJOINTS`, and when to use which, are described in
docs/gradients.md ("Which mode"): `"checkpoint"` (`RecursiveCheckpointAdjoint`, the
default) and `"forward"` (`ForwardMode`, for `jax.jacfwd`) give the exact derivative of the
discrete solution; `"backsolve"` (`BacksolveAdjoint(throw=True)`) approximates it.

The `throw=True` is the numerical trap of this module: the env solves with `throw=False`
(a failure is reported in `info["solver_ok"]`), a plain `BacksolveAdjoint()` passes that on
to its backward solve, and a failed backward solve then yields a finite, wrong gradient
that nothing reports (900 times too large on one step of `make("VanDerPol", mu=1000,
dt=1)` with Kvaerno5, `tests/test_gradients.py`). The named adjoint raises instead; a plain
one warns (`warn_if_silent`).

JAX refuses forward mode through diffrax's solve loop (a `custom_vjp`) with a message that
names no fix; `forward_mode_hint` re-raises it naming one.
"""

import contextlib
import warnings

import diffrax
import equinox as eqx


ADJOINTS: tuple[str, ...] = ("checkpoint", "forward", "backsolve")
"""Names accepted by `make_adjoint` and `with_adjoint`."""

CHECKPOINTS = 8
"""States that reverse mode keeps per solve (`diffrax.RecursiveCheckpointAdjoint(checkpoints=...)`)
when the adjoint does not say: see `sized_to_the_work`."""


def sized_to_the_work(adjoint: diffrax.AbstractAdjoint, max_steps: int) -> diffrax.AbstractAdjoint:
    """`adjoint`, with a `RecursiveCheckpointAdjoint` that names no checkpoint count given `CHECKPOINTS`.

    Why, and what it costs (Stumm and Walther's online schedule recomputes more beyond 44 steps,
    with the same gradient to the last bit): docs/gradients.md, "Per solve". Measured on
    `CartPoleContinuous(integrator="tsit5")`, 64 envs x 100 steps: 81 MiB of XLA temp memory
    with diffrax's count (about `sqrt(2 max_steps)`), 4 MiB with 4 checkpoints, at the same
    time (`benchmarks/gradient_cost.py`).
    """
    if type(adjoint) is diffrax.RecursiveCheckpointAdjoint and adjoint.checkpoints is None:
        return diffrax.RecursiveCheckpointAdjoint(checkpoints=min(CHECKPOINTS, max_steps))
    return adjoint


def make_adjoint(adjoint: "str | diffrax.AbstractAdjoint") -> diffrax.AbstractAdjoint:
    """A diffrax adjoint from its name in `ADJOINTS` (an adjoint object passes through)."""
    if isinstance(adjoint, diffrax.AbstractAdjoint):
        return adjoint
    if adjoint == "checkpoint":
        return diffrax.RecursiveCheckpointAdjoint()
    if adjoint == "forward":
        return diffrax.ForwardMode()
    if adjoint == "backsolve":
        # The env's solves run with throw=False, which the backward solve would inherit.
        return diffrax.BacksolveAdjoint(throw=True)
    raise ValueError(f"adjoint must be one of {ADJOINTS} or a diffrax adjoint, got {adjoint!r}")


# The text of JAX's refusal (jax 0.10; the same since 0.4) of forward mode through a custom_vjp.
_JVP_OF_CUSTOM_VJP = "can't apply forward-mode autodiff (jvp) to a custom_vjp function"


@contextlib.contextmanager
def forward_mode_hint(adjoint: diffrax.AbstractAdjoint):
    """Re-raise JAX's refusal of forward mode through a reverse-mode adjoint with the fix named.

    Only under an adjoint other than `ForwardMode`, and once (a nested use passes it on).
    """
    try:
        yield
    except TypeError as error:
        if _JVP_OF_CUSTOM_VJP not in str(error) or isinstance(adjoint, diffrax.ForwardMode) or "with_adjoint" in str(error):
            raise
        raise TypeError(
            f"forward-mode autodiff (jax.jacfwd, jax.jvp) cannot pass the env's adjoint "
            f"{type(adjoint).__name__}, which is reverse mode only (JAX: {error}). For forward mode use "
            "env = lerax_like.with_adjoint(env, 'forward'); for reverse mode, jax.grad or jax.vjp."
        ) from error


def warn_if_silent(adjoint: diffrax.AbstractAdjoint) -> None:
    """Warn about a `BacksolveAdjoint` whose backward solve would fail silently.

    The env's solves run with `throw=False`; a `BacksolveAdjoint` not given `throw=True`
    inherits it for its backward solve, whose failure (an exhausted budget, on stiff
    dynamics) then returns a wrong gradient without a word.
    """
    if isinstance(adjoint, diffrax.BacksolveAdjoint) and adjoint.kwargs.get("throw") is not True:
        warnings.warn(
            "BacksolveAdjoint without throw=True: the env solves with throw=False (failures go to "
            "info['solver_ok']) and the backward solve inherits it, so when the backward solve fails "
            "(an exhausted max_steps, typical on stiff dynamics) the gradient is wrong and nothing says so. "
            "Use make_adjoint('backsolve') or diffrax.BacksolveAdjoint(throw=True).",
            UserWarning,
            stacklevel=3,
        )


def with_adjoint(env, adjoint: "str | diffrax.AbstractAdjoint"):
    """`env` with its integrator's adjoint replaced (a name from `ADJOINTS` or a diffrax adjoint).

    Works on any env (or other module) with an `integrator` field; returns a new env.
    Warns on a `BacksolveAdjoint` that would fail silently (see `warn_if_silent`).
    """
    adjoint = make_adjoint(adjoint)
    warn_if_silent(adjoint)
    return eqx.tree_at(lambda e: e.integrator, env, env.integrator.with_adjoint(adjoint))
