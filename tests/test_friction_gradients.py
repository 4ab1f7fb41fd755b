"""Gradients through located stick-slip switches against central finite differences (float64).

The friction cart-pole (`CartFriction`, mu_s = 0.3, mu_k = 0.15, a 0.3 kg pole let go at rest
from 1 rad, no force): the cart sticks, is released by the falling pole (a located release,
set by mu_s), slides, stops and sticks again (set by mu_k), and is released again, within 40
steps of 0.02 s. A rollout loss differentiated with respect to the start angle, mu_s and mu_k,
for every explicit solver preset at its default settings: reverse mode batched with `jax.vmap`
over the start and its shifted copies (distinct starts); the same gradient unbatched, and
forward mode (`jax.jacfwd`, `ForwardMode`) batched, for Euler, RK4 and Tsit5. Each within 1e-6 relative
of central differences of the same rollout, with the same switches at every shifted point.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from conftest import jacfwd_and_value


EXPLICIT = [name for name, preset in ll.SOLVERS.items() if not preset.implicit]
# Forward mode on a first-order, a fixed-step fourth-order and an adaptive solver: each
# preset's compile costs about a minute of one core, and CI runs the whole suite.
FORWARD = ["euler", "rk4", "tsit5"]
# The unbatched reverse-mode program on the same three: a second program of a minute's compile
# for each preset, where the batched one (every preset, above) is what a user runs.
UNBATCHED = FORWARD
STEPS = 40
THETA = np.array([1.0, 0.3, 0.15])  # start angle, mu_s, mu_k


def _loss_of(env):
    def loss(theta):
        e = eqx.tree_at(
            lambda e: (e.friction[0].cart_static_friction, e.friction[0].cart_kinetic_friction), env, (theta[1], theta[2])
        )
        y0 = jnp.stack([jnp.zeros_like(theta[0]), jnp.zeros_like(theta[0]), theta[0], jnp.zeros_like(theta[0])])
        ys, info = ll.rollout(e, ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int)), jnp.zeros((STEPS, 1)))
        value = jnp.sum(ys[:, 0] ** 2 + ys[:, 1] ** 2) + 0.1 * jnp.sum(jnp.cos(ys[:, 2]))
        stuck_steps = jnp.sum(ys[:, 1] == 0.0)
        return value, (jnp.sum(info["switches"]), stuck_steps, jnp.all(info["solver_ok"]))

    return loss


def _points():
    steps = 1e-6 * np.maximum(1.0, np.abs(THETA))
    shifts = [np.zeros(3)] + [sign * steps[i] * np.eye(3)[i] for i in range(3) for sign in (1, -1)]
    return jnp.asarray(THETA + np.array(shifts)), steps


def _central(values, steps):
    return np.array([(values[1 + 2 * i] - values[2 + 2 * i]) / (2 * steps[i]) for i in range(3)])


def _check(ad, fd, label):
    relative = np.abs(np.asarray(ad) - fd) / np.abs(fd)
    assert np.all(relative <= 1e-6), f"{label}: AD {ad}, FD {fd}, relative error {relative}"


def _env(solver):
    return ll.make("CartPoleContinuous",
        cart_static_friction=0.3, cart_kinetic_friction=0.15, pole_mass=0.3,
        x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, solver=solver,
    )


@pytest.mark.slow
@pytest.mark.parametrize("solver", EXPLICIT)
def test_reverse_mode_through_stick_slip_matches_central_differences(solver):
    loss = _loss_of(_env(solver))
    points, steps = _points()
    (values, (switches, stuck, ok)), grads = jax.jit(jax.vmap(jax.value_and_grad(loss, has_aux=True)))(points)
    assert bool(jnp.all(ok))
    assert int(jnp.min(switches)) == int(jnp.max(switches)) >= 3, switches  # release, stick, release
    assert int(jnp.min(stuck)) == int(jnp.max(stuck)) >= 1
    fd = _central(np.asarray(values), steps)
    _check(grads[0], fd, f"{solver} vmapped")
    if solver in UNBATCHED:
        single = jax.jit(jax.grad(lambda theta: loss(theta)[0]))(points[0])
        _check(single, fd, f"{solver} single")


@pytest.mark.slow
@pytest.mark.parametrize("solver", FORWARD)
def test_forward_mode_through_stick_slip_matches_central_differences(solver):
    loss = _loss_of(ll.with_adjoint(_env(solver), "forward"))
    points, steps = _points()
    # One program: the Jacobians and, as their auxiliary output, the primal values.
    jacobians, (values, (switches, _, ok)) = jax.jit(jax.vmap(jacfwd_and_value(loss)))(points)
    assert bool(jnp.all(ok)) and int(jnp.min(switches)) == int(jnp.max(switches)) >= 3
    _check(jacobians[0], _central(np.asarray(values), steps), f"{solver} forward, vmapped")
