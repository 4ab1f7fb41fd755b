"""Trajectory optimisation (the notebook `trajectory_optimisation.ipynb`), with a smaller budget."""

import jax.numpy as jnp
import jax.random as jr
import pytest

import lerax_like as ll
from lerax_like.control.learning import optimise_open_loop, rollout_states
from lerax_like.env import EnvState


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_swing_up_reaches_upright():
    inf = float("inf")
    env = ll.make("CartPoleContinuous", solver="rk4", theta_threshold_radians=inf, x_threshold=inf)
    y0 = jnp.array([0.0, 0.0, jnp.pi, 0.0])

    def objective(ys):
        return 5 * (1 - jnp.cos(ys[-1, 2])) + 0.1 * ys[-1, 3] ** 2 + 0.001 * jnp.mean(ys[:, 0] ** 2)

    actions, history = optimise_open_loop(env, y0, objective, horizon=150, action_size=1, iterations=500, key=jr.key(1))
    ys = rollout_states(env, EnvState(y=y0, steps=jnp.zeros((), dtype=int)), actions)
    # From hanging (error pi) to within 0.1 rad of upright at the end.
    assert float(jnp.abs(jnp.arctan2(jnp.sin(ys[-1, 2]), jnp.cos(ys[-1, 2])))) < 0.1
    assert float(history[-1]) < 0.01 * float(history[0])
