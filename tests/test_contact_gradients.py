"""Gradients through located impacts against central finite differences (float64).

A 50-step rollout loss through at least two impacts, differentiated with respect to an initial
state component, a physical parameter and the restitution, for every explicit solver preset,
on `BouncingBall` (a wall, then the floor): AD, in reverse mode (the default, event times
differentiated implicitly) and in forward mode (batched over the shifted points, whose
primal values are the differences' values), within 1e-6 relative of central differences of
the same rollout. Reverse mode batched over the ball's distinct resets, where the envs of a
batch strike at different times (the batching's own failure, issue 29), is checked with
Euler and Tsit5 in tests/test_batched_gradients.py. The walled cart-pole's impacts (a
chain's impact map: restitution, physical parameters and start, through a second impact)
are checked the same way, batched over distinct resets and in both modes, with Euler, RK4
and Tsit5, in tests/test_batched_gradients.py.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from conftest import jacfwd_and_value


EXPLICIT = [name for name, preset in ll.SOLVERS.items() if not preset.implicit]
STEPS = 50


def _ball(solver):
    env = ll.make("BouncingBall", restitution=0.8, solver=solver)
    # Thrust towards the wall from a height: the wall at about 0.4 s, the floor at 0.45 s.
    y0 = jnp.array([0.5, 1.0, 1.0, 0.0])
    actions = jnp.tile(jnp.array([0.3, 0.0]), (STEPS, 1))
    return env, y0, actions, lambda e: e.dynamics.gravity


def _check_against_central_differences(loss, theta, min_impacts: int, label: str, forward_loss=None) -> None:
    """AD of `loss` (returning the value and `(impacts, all solves ok)`) at `theta` within 1e-6
    relative of central differences, the same impacts at every shifted point: reverse mode,
    and forward mode (`jax.jacfwd`) of `forward_loss` where given (the same loss through an
    env with the forward-mode adjoint)."""
    n = theta.shape[0]
    steps = 1e-6 * np.maximum(1.0, np.abs(np.asarray(theta)))
    shifts = [np.zeros(n)] + [sign * steps[i] * np.eye(n)[i] for i in range(n) for sign in (1, -1)]
    points = theta + jnp.asarray(np.array(shifts))

    # One compiled program. With a forward-mode loss: its derivatives batched over the points,
    # whose primal values there are the central differences' values, and reverse mode's
    # gradient at theta. Without: reverse mode batched over the points.
    @jax.jit
    def derivatives(points):
        if forward_loss is None:
            return jax.vmap(jax.value_and_grad(loss, has_aux=True))(points), None

        forward, (values, (impacts, ok)) = jax.vmap(jacfwd_and_value(forward_loss))(points)
        (_, (impact, fine)), grad = jax.value_and_grad(loss, has_aux=True)(points[0])
        return ((values, (jnp.append(impacts, impact), jnp.append(ok, fine))), grad[None]), forward

    ((values, (impacts, ok)), grads), forward = derivatives(points)
    assert bool(jnp.all(ok))
    assert int(jnp.min(impacts)) == int(jnp.max(impacts)) >= min_impacts  # the same impacts at every point
    fd = np.array([(values[1 + 2 * i] - values[2 + 2 * i]) / (2 * steps[i]) for i in range(n)])
    for mode, ad in (("reverse", grads), ("forward", forward)):
        if ad is None:
            continue
        ad = np.asarray(ad[0])
        relative = np.abs(ad - fd) / np.abs(fd)
        assert np.all(relative <= 1e-6), f"{label}, {mode} mode: AD {ad}, FD {fd}, relative error {relative}"


# Every explicit preset's gradient through located impacts, in both modes, is checked here
# (tests/test_batched_gradients.py checks the walled cart-pole's, a chain's impact map, with
# Euler, RK4 and Tsit5).
@pytest.mark.slow
@pytest.mark.parametrize("solver", EXPLICIT)
def test_rollout_gradient_through_impacts_matches_finite_differences(solver):
    env, y0, actions, physical = _ball(solver)

    def loss_through(env):
        def loss(theta):
            # theta: the initial x, a physical parameter, the restitution.
            e = eqx.tree_at(lambda e: (physical(e), e.contacts[0].restitution), env, (theta[1], theta[2]))
            state = ll.EnvState(y=y0.at[0].set(theta[0]), steps=jnp.zeros((), dtype=int))
            ys, info = ll.rollout(e, state, actions)
            value = jnp.sum(ys[:, :2] ** 2) + 0.1 * jnp.sum(ys[:, 2:] ** 2)
            return value, (jnp.sum(info["impacts"]), jnp.all(info["solver_ok"]))

        return loss

    theta = jnp.array([y0[0], float(physical(env)), 0.8])
    _check_against_central_differences(
        loss_through(env), theta, 2, solver, forward_loss=loss_through(ll.with_adjoint(env, "forward"))
    )


@pytest.mark.slow
def test_rimless_wheel_gradient_through_heel_strikes_matches_finite_differences():
    # The passive wheel over 60 env steps (3 s, several heel strikes, each relabelling the
    # stance angle and scaling the speed by cos(2 alpha)): the gradient of a rollout loss
    # with respect to the start speed, the slope and the spoke half-angle, which moves
    # both the strike surface and the impact map.
    env = ll.make("RimlessWheel", solver="tsit5")
    wheel = env.dynamics
    actions = jnp.zeros((60, 1))

    def loss(theta):
        e = eqx.tree_at(lambda e: (e.dynamics.slope, e.dynamics.spoke_half_angle), env, (theta[1], theta[2]))
        y0 = jnp.stack([theta[1] - theta[2], theta[0]])  # just after a strike
        ys, info = ll.rollout(e, ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int)), actions)
        value = jnp.sum(jnp.sin(ys[:, 0]) ** 2 + 0.1 * ys[:, 1] ** 2)
        return value, (jnp.sum(info["impacts"]), jnp.all(info["solver_ok"]))

    theta = jnp.array([1.5, float(wheel.slope), float(wheel.spoke_half_angle)])
    _check_against_central_differences(loss, theta, 3, "RimlessWheel")
