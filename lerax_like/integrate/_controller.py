"""A PID step-size controller that survives a trial step diverging to infinity."""

import diffrax
import jax
import jax.numpy as jnp


class GuardedPIDController(diffrax.PIDController):
    """`diffrax.PIDController`, which also shrinks the step after a trial step that diverged to infinity.

    diffrax 0.7.2 scales a step's error by `atol + rtol max(|y0|, |y1|)`, with `y0` alone
    when the candidate `y1` is NaN. A root finder that diverges to infinity (Kvaerno4 on
    Van der Pol at `mu = 1e3`) gives an infinite `y1` and error: `inf / inf` is NaN, so is
    the next step size, and every later step is rejected until `max_steps` (0 of 100000
    accepted). Here a non-finite candidate counts as NaN with an infinite error, which the
    controller rejects and answers with a step `factormin` times smaller. `Integrator`
    solves with this in place of a plain `PIDController` of the same settings.
    """

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        diverged = jnp.any(jnp.stack([jnp.any(~jnp.isfinite(y)) for y in jax.tree.leaves(y1_candidate)]))
        y1_candidate = jax.tree.map(lambda y: jnp.where(diverged, jnp.nan, y), y1_candidate)
        y_error = jax.tree.map(lambda e: jnp.where(diverged, jnp.inf, e), y_error)
        return super().adapt_step_size(t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state)
