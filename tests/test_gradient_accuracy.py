"""The gradient of the discretised env against the continuous system's."""

import jax.numpy as jnp
import numpy as np

import lerax_like as ll
from lerax_like.analysis.gradient_accuracy import trajectory_sensitivity, with_integrator


INF = float("inf")


def _sensitivities(integrator, steps=100):
    env = with_integrator(ll.CartPoleContinuous(theta_threshold_radians=INF, x_threshold=INF), integrator)
    y0 = jnp.array([0.0, 0.0, jnp.pi - 0.3, 0.0])
    actions = 0.5 * jnp.sin(0.1 * jnp.arange(steps, dtype=jnp.float64))[:, None]
    return np.asarray(trajectory_sensitivity(env, lambda e: e.dynamics.half_length, y0, actions)[:, 2])


def test_euler_gradient_is_first_order_and_can_have_the_wrong_sign():
    reference = _sensitivities(ll.make_integrator("rk4", substeps=8))  # ~1e-9 from Dopri8 at rtol 1e-12
    euler = _sensitivities(ll.make_integrator("euler"))
    euler_half_step = _sensitivities(ll.make_integrator("euler", substeps=2))
    # Order 1: halving the step about halves the error of the sensitivity.
    ratio = np.linalg.norm(euler - reference) / np.linalg.norm(euler_half_step - reference)
    assert 1.5 < ratio < 2.6
    # A swing from near hanging: d theta / d half_length after 92 steps (1.84 s) has the
    # opposite sign under Gymnasium's Euler at dt = 0.02, both of order 1.
    assert euler[92] * reference[92] < 0
    assert min(abs(euler[92]), abs(reference[92])) > 1.0
