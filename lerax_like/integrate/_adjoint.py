"""Choosing how gradients pass through the solves of an env: the adjoint.

Every env step is a `diffrax.diffeqsolve`, so the adjoint method is a property of the
env's `Integrator`. Three are useful:

- `"checkpoint"`, `diffrax.RecursiveCheckpointAdjoint()` (the default): reverse mode
  through the solver's own steps, with recursive checkpointing. The gradient is the exact
  derivative of the *discrete* solution the env produces, whatever the solver (explicit,
  adaptive or implicit; the root finder of an implicit solver is differentiated
  implicitly). It does not support forward mode.
- `"forward"`, `diffrax.ForwardMode()`: forward mode through the solver's steps, for
  `jax.jacfwd` / `jax.jvp`. Also the exact derivative of the discrete solution; cheap
  when there are few inputs (a force, a few parameters) and many outputs.
- `"backsolve"`, `diffrax.BacksolveAdjoint(throw=True)`: the continuous adjoint ODE,
  solved backwards in time with the same solver. It is an *approximation* of the
  gradient of the discrete solution (it approximates the continuous system's gradient
  instead), with an error of the order of the solver's error. It reconstructs the state
  backwards in time, which is unstable where the dynamics contract fast (stiff or
  strongly dissipative systems): the backward solve then needs far more steps than the
  forward one and exhausts `max_steps`. The env solves with `throw=False` (a failure is
  reported in `info["solver_ok"]`, not raised), and a plain `diffrax.BacksolveAdjoint()`
  passes that on to its backward solve, whose failure then yields a finite, wrong
  gradient that nothing reports: 900 times too large on one step of
  `make("VanDerPol", mu=1000, dt=1)` with Kvaerno5 (`tests/test_gradients.py`). The named
  adjoint gives the backward solve `throw=True`, so that this failure raises; a plain
  one warns (`warn_if_silent`). A backward solve that succeeds can still drift from the
  forward trajectory (README, Gradients): prefer `"checkpoint"` on stiff dynamics.

Pick one with `with_adjoint(env, "forward")`, or build the scene with an `Integrator`:
`CartPoleContinuous(integrator=make_integrator("tsit5", adjoint=diffrax.ForwardMode()))`.

`jax.jacfwd` (or `jax.jvp`) of a rollout or step under `"checkpoint"` fails wherever the
step runs diffrax's solve loop (an adaptive or implicit solver, `substeps > 1`, located
contacts): that loop is a `custom_vjp`, which JAX refuses to push tangents through. JAX's
own message ("can't apply forward-mode autodiff (jvp) to a custom_vjp function") names no
fix; `rollout` and the env step re-raise it with the fix named (`forward_mode_hint`).
Where the refusal surfaces outside them (`jax.jacfwd(jax.jit(loss))`: JAX differentiates
the compiled function after tracing it), JAX's own message is all there is.
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

    diffrax sizes the checkpoints of a solve by its step budget (about `sqrt(2 max_steps)`:
    90 for the 4096 steps of an adaptive env step), and reverse mode allocates and carries all of
    them whether the solve takes 2 steps or 4000. An env step of 0.02 s takes a handful, so 8
    hold every step of a solve of up to 44 steps with no recomputation beyond one forward sweep
    (Stumm and Walther's online schedule, `equinox.internal.while_loop`); a longer solve is
    recomputed more, never wrong: the gradient is the same, to the last bit. Measured on
    `CartPoleContinuous(integrator="tsit5")`, 64 envs x 100 steps: 81 MiB of XLA temp memory with
    diffrax's count, 4 MiB with 4 checkpoints, at the same time (`benchmarks/gradient_cost.py`).
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
