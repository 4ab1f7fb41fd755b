"""When do the simulator's gradients pay? Gradient variance, bias and chaos, per scene and solver.

The question of Suh, Simchowitz, Zhang and Tedrake, "Do Differentiable Simulators Give
Better Policy Gradients?" (ICML 2022), measured on this package's envs. The objective is
the Gaussian smoothing of a rollout cost,

    F(theta) = E_w[f(theta + sigma w)],  w ~ N(0, I),

where `theta` parametrises the actions over a horizon of `H` env steps (an open-loop
action sequence, or the gain of a linear state feedback) and `f` is the total quadratic
cost of the rollout from a fixed start. Two estimators of `grad F` over `N` samples:

- `first_order`: the mean of `grad f(theta + sigma w)`, the gradient through the simulator;
- `zeroth_order`: the mean of `(f(theta + sigma w) - f(theta)) w / sigma`, black box;
- `alpha_order`: the paper's interpolation `alpha first + (1 - alpha) zeroth`, with `alpha`
  chosen to minimise the variance, and 0 when the two disagree by more than three
  standard errors (the paper's guard against the first-order estimator's bias).

Each is reported with its norm, its variance (the trace of the per-sample covariance)
and its bias against a reference `grad F`, all with standard errors. The reference is a
zeroth-order estimate with antithetic samples, `(f(theta + sigma w) - f(theta - sigma w))
w / (2 sigma)`, over many samples: by Stein's lemma it is unbiased for `grad F` whether
or not `f` is differentiable, and it never uses the simulator's derivative, so it can
expose a bias of the first-order estimator (the first-order mean over many samples could
not: it would share that bias).

Beside them: the finite-time Lyapunov exponent of the nominal trajectory (QR
renormalisation of the product of the step Jacobians), the horizon past which the
first-order variance is then expected to exceed the zeroth-order one, the horizon where
it is measured to, and the horizon at which the float32 gradient has lost its leading
correct digit against float64.

The study's shape, as the other two studies': a `GradientVarianceConfig` (frozen,
checked), its run (`run_gradient_variance(config) -> GradientVarianceResult`) and the result
(`rows`, `record`), whose files `write_gradient_variance` (`result.write`) writes through
`recording`, the one writer. Only the run reads the configuration; what it calls takes
values. The objective is in `_objective`, the float32 digit loss and the crossover in
`_precision`; the estimators and the Lyapunov exponents are gradient tools of
`lerax_like.gradients`, the figure is in `analysis.figures`, the table in `analysis.tables`.
"""

from ..figures import plot_gradient_variance as plot_gradient_variance
from ..tables import format_gradient_variance_table as format_gradient_variance_table
from ._objective import (
    POLICIES as POLICIES,
    action_size as action_size,
    active_parameters as active_parameters,
    build_env as build_env,
    closed_loop_step as closed_loop_step,
    initial_state as initial_state,
    lqr_gain as lqr_gain,
    nominal_gain as nominal_gain,
    nominal_parameters as nominal_parameters,
    objective as objective,
    policy_action as policy_action,
    stage_costs as stage_costs,
    step_state as step_state,
)
from ._precision import (
    precision_at_horizons as precision_at_horizons,
    precision_loss as precision_loss,
    truncated_gradients as truncated_gradients,
    variance_crossover as variance_crossover,
)
from ._study import (
    CONTACT_GAP as CONTACT_GAP,
    DESCRIPTIONS as DESCRIPTIONS,
    GRADIENT_VARIANCE_CSV_COLUMNS as GRADIENT_VARIANCE_CSV_COLUMNS,
    GradientVarianceConfig as GradientVarianceConfig,
    GradientVarianceResult as GradientVarianceResult,
    file_stem as file_stem,
    run_gradient_variance as run_gradient_variance,
    summary as summary,
    write_gradient_variance as write_gradient_variance,
)
