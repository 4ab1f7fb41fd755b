"""The classic fourth-order Runge--Kutta method, which diffrax does not ship."""

from collections.abc import Callable
from typing import ClassVar

import diffrax
import numpy as np


class RK4(diffrax.AbstractERK):
    """Classic fourth-order Runge--Kutta method (Kutta, 1901) as a diffrax solver.

    Four stages, no error estimate: use it with `diffrax.ConstantStepSize` (or
    `diffrax.StepTo`); `make_integrator` refuses it under an adaptive controller.
    Third-order Hermite interpolation for dense output.
    """

    tableau: ClassVar[diffrax.ButcherTableau] = diffrax.ButcherTableau(
        c=np.array([0.5, 0.5, 1.0]),
        b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
        # Classic RK4 has no embedded method; a zero error estimate marks that. It would make
        # an adaptive controller accept every step, hence the refusal above.
        b_error=np.zeros(4),
        a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
    )
    interpolation_cls: ClassVar[Callable[..., diffrax.AbstractLocalInterpolation]] = (
        diffrax.ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        return 4
