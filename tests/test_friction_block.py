"""Coulomb stick-slip on `SlidingBlock` against closed forms (`lerax_like.stick_slip`).

- A block launched at `v0` on the level stops at `t = v0 / (mu_k g)` after `v0^2 / (2 mu_k g)`
  (Tsit5 and RK4 at their default settings), and the distance's derivative with respect to
  `mu_k` is `-v0^2 / (2 mu_k^2 g)` (reverse and forward mode, single and vmapped over starts);
- on an incline it stays at rest iff `tan(alpha) <= mu_s`, exactly (to the last bit) for 10^4
  steps under a sub-threshold load, and slides off above the threshold;
- bad coefficients are refused by name; a stop and reversal through zero is one located switch.
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll


G, MU_S, MU_K = 9.81, 0.5, 0.3
SPEEDS = (2.0, 1.3, 0.7)


def _state(y):
    return ll.EnvState(y=jnp.asarray(y, dtype=jnp.float64), steps=jnp.zeros((), dtype=int))


def _block(**keywords):
    return ll.make("SlidingBlock", **{"static_friction": MU_S, "kinetic_friction": MU_K, "gravity": G, **keywords})


def _stop(env, v0):
    """The stop time and position of a block launched at `v0` from 0 on the level, unpushed."""
    actions = jnp.zeros((20, 1))
    ys, info = ll.rollout(env, _state(jnp.stack([jnp.zeros_like(v0), v0])), actions)
    switched = info["switches"] > 0
    index = jnp.argmax(switched)
    time = index.astype(env.dt.dtype) * env.dt + jnp.where(switched, info["first_switch_time"], 0.0)[index]
    return time, ys[-1, 0], ys[-1, 1], jnp.sum(info["switches"]), jnp.all(info["solver_ok"])


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["tsit5", "rk4"])
def test_launched_block_stops_at_the_closed_form_time_and_distance(solver):
    env = _block(solver=solver)
    times, positions, speeds, switches, ok = jax.jit(jax.vmap(lambda v0: _stop(env, v0)))(jnp.asarray(SPEEDS))
    assert bool(jnp.all(ok)) and np.all(np.asarray(switches) == 1)
    v0 = np.asarray(SPEEDS)
    np.testing.assert_allclose(times, v0 / (MU_K * G), rtol=0, atol=1e-10)
    np.testing.assert_allclose(positions, v0**2 / (2 * MU_K * G), rtol=0, atol=1e-10)
    assert np.all(np.asarray(speeds) == 0.0)  # at rest exactly, not to round-off


@pytest.mark.slow
def test_stopping_distance_gradient_in_kinetic_friction_matches_the_closed_form():
    # d/dmu_k of v0^2 / (2 mu_k g), by reverse mode and by forward mode, single and vmapped
    # over launch speeds (distinct starts).
    env = _block()

    def distance(mu_k, v0, e):
        e = eqx.tree_at(lambda e: e.friction[0].kinetic_friction, e, mu_k)
        return _stop(e, v0)[1]

    expected = -np.asarray(SPEEDS) ** 2 / (2 * MU_K**2 * G)
    single = jax.jit(jax.grad(distance))(jnp.asarray(MU_K), jnp.asarray(SPEEDS[0]), env)
    assert abs(float(single) - expected[0]) <= 1e-8
    mu = jnp.full(len(SPEEDS), MU_K)
    reverse = jax.jit(jax.vmap(jax.grad(distance), in_axes=(0, 0, None)))(mu, jnp.asarray(SPEEDS), env)
    forward_env = ll.with_adjoint(env, "forward")
    forward = jax.jit(jax.vmap(jax.jacfwd(distance), in_axes=(0, 0, None)))(mu, jnp.asarray(SPEEDS), forward_env)
    np.testing.assert_allclose(reverse, expected, rtol=0, atol=1e-8)
    np.testing.assert_allclose(forward, expected, rtol=0, atol=1e-8)


@pytest.mark.slow
def test_block_under_a_sub_threshold_load_stays_exactly_at_rest_for_ten_thousand_steps():
    # tan(0.4) = 0.423 <= mu_s = 0.5, and a push up the slope of 1 N on a 1 kg block:
    # the holding force m g sin(alpha) - 1 = 2.82 N is below mu_s m g cos(alpha) = 4.52 N.
    env = _block(incline=0.4)
    y0 = jnp.array([0.25, 0.0])
    actions = jnp.full((10_000, 1), 1.0 / float(env.force_mag))
    ys, info = jax.jit(ll.rollout)(env, _state(y0), actions)
    assert bool(jnp.all(info["solver_ok"]))
    assert np.all(np.asarray(ys) == np.asarray(y0)), "the block crept"
    assert int(jnp.sum(info["switches"])) == 0


@pytest.mark.slow
def test_block_on_an_incline_holds_iff_tan_alpha_is_at_most_mu_s():
    threshold = math.atan(MU_S)
    inclines = jnp.array([0.0, 0.2, threshold - 1e-6, threshold + 1e-6, 0.6])

    def after(incline):
        env = _block(incline=incline)
        ys, info = ll.rollout(env, _state(jnp.array([0.0, 0.0])), jnp.zeros((10, 1)))
        return ys[-1], jnp.all(info["solver_ok"])

    ends, ok = jax.jit(jax.vmap(after))(inclines)
    assert bool(jnp.all(ok))
    holds = np.asarray(jnp.all(ends == 0.0, axis=1))
    np.testing.assert_array_equal(holds, np.tan(np.asarray(inclines)) <= MU_S)
    # Above the threshold it slides down with a = g (sin - mu_k cos), from rest at t = 0.
    t = 10 * 0.05
    acceleration = G * (np.sin(0.6) - MU_K * np.cos(0.6))
    np.testing.assert_allclose(ends[-1], [-0.5 * acceleration * t**2, -acceleration * t], rtol=1e-12)


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_bad_friction_is_refused_by_name_and_a_reversal_is_one_switch():
    with pytest.raises(ValueError, match="max_events"):
        _block(max_events=0)
    with pytest.raises(ValueError, match="kinetic friction coefficient must not exceed"):
        _block(static_friction=0.2, kinetic_friction=0.3)
    with pytest.raises(ValueError, match="incline"):
        _block(incline=2.0)
    # Launched up a slope it cannot hold on (tan 0.6 > mu_s) at 1 m/s: it stops after
    # 1 / (g (sin + mu_k cos)) = 0.0987 s and slides back down, one switch (the stop and
    # the reversal through zero are one located event), within a budget of one.
    env = _block(incline=0.6, max_events=1, dt=0.5)
    state, info = jax.jit(lambda s: env.evolve(s, jnp.zeros(1)))(_state([0.0, 1.0]))
    assert bool(info["solver_ok"]) and int(info["switches"]) == 1
    stop = 1.0 / (G * (np.sin(0.6) + MU_K * np.cos(0.6)))
    assert abs(float(info["first_switch_time"]) - stop) <= 1e-12
    down = G * (np.sin(0.6) - MU_K * np.cos(0.6))
    assert abs(float(state.y[1]) + down * (0.5 - stop)) <= 1e-12
