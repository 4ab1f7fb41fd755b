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
- `"backsolve"`, `diffrax.BacksolveAdjoint()`: the continuous adjoint ODE, solved
  backwards in time with the same solver. It is an *approximation* of the gradient of the
  discrete solution (it approximates the continuous system's gradient instead), with an
  error of the order of the solver's error; it reconstructs the state backwards, which is
  unstable for stiff or dissipative systems and then returns NaN or garbage.

Pick one with `with_adjoint(env, "forward")`, or build the scene with an `Integrator`:
`CartPoleContinuous(solver=make_integrator("tsit5", adjoint=diffrax.ForwardMode()))`.
"""

import diffrax
import equinox as eqx


ADJOINTS: tuple[str, ...] = ("checkpoint", "forward", "backsolve")
"""Names accepted by `make_adjoint` and `with_adjoint`."""


def make_adjoint(adjoint: "str | diffrax.AbstractAdjoint") -> diffrax.AbstractAdjoint:
    """A diffrax adjoint from its name in `ADJOINTS` (an adjoint object passes through)."""
    if isinstance(adjoint, diffrax.AbstractAdjoint):
        return adjoint
    if adjoint == "checkpoint":
        return diffrax.RecursiveCheckpointAdjoint()
    if adjoint == "forward":
        return diffrax.ForwardMode()
    if adjoint == "backsolve":
        return diffrax.BacksolveAdjoint()
    raise ValueError(f"adjoint must be one of {ADJOINTS} or a diffrax adjoint, got {adjoint!r}")


def with_adjoint(env, adjoint: "str | diffrax.AbstractAdjoint"):
    """`env` with its integrator's adjoint replaced (a name from `ADJOINTS` or a diffrax adjoint).

    Works on any env (or other module) with an `integrator` field; returns a new env.
    """
    return eqx.tree_at(lambda e: e.integrator.adjoint, env, make_adjoint(adjoint))
