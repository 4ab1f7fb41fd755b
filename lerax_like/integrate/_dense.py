"""Dense output of a solver's own order (up to four) for Runge--Kutta methods without one."""

from typing import ClassVar

import diffrax


class HermiteDenseOutput(diffrax.AbstractAdaptiveSolver, diffrax.AbstractWrappedSolver):
    """`solver`'s steps, with cubic Hermite dense output from the vector field at both ends.

    diffrax gives an explicit Runge--Kutta method without an interpolant of its own
    (`interpolation_cls = ThirdOrderHermitePolynomialInterpolation.from_k`) a cubic
    Hermite polynomial whose slope at the step's end is the last *stage*, which is the
    vector field at the step's end only for a first-same-as-last method. For a hand-made
    third-order tableau whose last stage sits at `c = 3/4` (Ralston's), the dense error
    then converges at order 2. Here each step also evaluates the vector field at its end
    state (one evaluation more), so the interpolant matches the solution's value and slope
    at both ends and its error is `O(h^min(p, 4))` for a method of order `p`. The steps,
    error estimates and accepted states are the wrapped solver's.

    `Integrator.dense_states` wraps such solvers in this by itself; wrap one by hand to get
    the same dense output from `diffrax.diffeqsolve(..., saveat=SaveAt(ts=...))`.
    """

    solver: diffrax.AbstractSolver
    interpolation_cls: ClassVar = diffrax.ThirdOrderHermitePolynomialInterpolation

    @property
    def term_structure(self):
        return self.solver.term_structure

    @property
    def term_compatible_contr_kwargs(self):
        return self.solver.term_compatible_contr_kwargs

    def order(self, terms):
        return self.solver.order(terms)

    def error_order(self, terms):
        return self.solver.error_order(terms)

    def init(self, terms, t0, t1, y0, args):
        return self.solver.init(terms, t0, t1, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        y1, y_error, _, solver_state, result = self.solver.step(terms, t0, t1, y0, args, solver_state, made_jump)
        # `k0`, `k1` are slopes times the step (diffrax's `vf_prod` with the step's control),
        # the scale `ThirdOrderHermitePolynomialInterpolation` expects.
        control = terms.contr(t0, t1)
        k0 = terms.vf_prod(t0, y0, args, control)
        k1 = terms.vf_prod(t1, y1, args, control)
        return y1, y_error, dict(y0=y0, y1=y1, k0=k0, k1=k1), solver_state, result

    def func(self, terms, t0, y0, args):
        return self.solver.func(terms, t0, y0, args)


def needs_hermite_dense_output(solver: diffrax.AbstractSolver) -> bool:
    """Whether `solver` is an explicit Runge--Kutta method whose dense output ends on a stage
    that need not be the vector field at the step's end (see `HermiteDenseOutput`)."""
    tableau = getattr(solver, "tableau", None)
    return (
        isinstance(solver, diffrax.AbstractERK)
        and isinstance(tableau, diffrax.ButcherTableau)
        and not tableau.fsal
        and solver.interpolation_cls == diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )
