"""Gradients through every solver, checked against central finite differences.

The smooth cases: a loss of a short rollout, differentiated with respect to the physical
parameters (`env.dynamics` leaves), the force scale, the actions, the initial state and
`dt`. The non-smooth cases show what finite differences say where the env is not
differentiable: at a termination and at an action clip.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.gradients import gradcheck
from lerax_like.env import EnvState
from lerax_like.gradients import make_adjoint, with_adjoint


Y0 = jnp.array([0.1, -0.2, 0.3, 0.5])

# Relative tolerance of autodiff against finite differences: the gradient of a fixed-step
# solve is a polynomial-like function of its inputs; an adaptive solve moves its steps
# with the inputs, which autodiff does not see (diffrax stops gradients through the
# controller), so finite differences carry an O(rtol) extra term.
FIXED_STEP_RTOL = 1e-6
ADAPTIVE_RTOL = 1e-4


def _rollout_loss(tree):
    env = tree["env"]
    state = EnvState(y=tree["y0"], steps=jnp.zeros((), dtype=int))
    ys, _ = ll.rollout(env, state, tree["actions"], key=jr.key(0))
    return jnp.sum(ys[-1] ** 2) + jnp.sum(jnp.cos(ys[:, 2]))


def _continuous(solver):
    return ll.make("CartPoleContinuous", solver=solver, reward="smooth")


def _discrete(solver):
    return ll.make("CartPole", solver=solver)


# One line per scene: (name, constructor from a solver, actions, whether actions are differentiable).
# Scenes landing on other branches add a line here.
SCENES = [
    ("CartPoleContinuous", _continuous, jnp.linspace(-0.8, 0.7, 4)[:, None], True),
    ("CartPole", _discrete, jnp.array([1, 0, 0, 1]), False),
]


def _check(make_env, actions, differentiable_actions, solver, *, adjoint="checkpoint", mode="reverse", with_dt=True):
    env = with_adjoint(make_env(solver), adjoint)
    tree = {"env": env, "y0": Y0, "actions": actions}

    def where(t):
        selected = (t["env"].dynamics, t["env"].force_mag, t["y0"])
        if differentiable_actions:
            selected += (t["actions"],)
        if with_dt:
            selected += (t["env"].dt,)
        return selected

    return env, gradcheck(_rollout_loss, tree, where=where, mode=mode)


def _rtol(env):
    return ADAPTIVE_RTOL if env.integrator.adaptive else FIXED_STEP_RTOL


# Adaptive implicit Euler: the steps move with the inputs, which finite differences see and
# autodiff does not (diffrax stops gradients through the controller). For a first-order
# method that term is O(h), and h ~ sqrt(rtol): measured, autodiff and finite differences
# differ by up to 2e-2 at the preset's rtol 1e-3 and still by 5e-4 at rtol 1e-6. So its
# gradient is checked on constant steps (stage root-finder tolerances set explicitly by
# the preset), where it is the exact gradient of the discrete map.
PRESET_CONTROLLERS = {"implicit_euler": diffrax.ConstantStepSize()}


# Through adaptive solves the gradient takes 7 to 18 s per preset on 2 cores.
@pytest.mark.parametrize(
    "preset",
    [pytest.param(p, marks=pytest.mark.slow) if ll.make_integrator(p).adaptive else p for p in ll.SOLVERS.names],
)
def test_every_preset_matches_finite_differences(preset):
    name, make_env, actions, differentiable = SCENES[0]
    solver = preset
    if preset in PRESET_CONTROLLERS:
        solver = ll.make_integrator(preset, PRESET_CONTROLLERS[preset])
    env, report = _check(make_env, actions, differentiable, solver)
    expected = {"['env'].dynamics.pole_mass", "['env'].dynamics.half_length", "['env'].dt", "['y0']", "['actions']"}
    assert expected <= {leaf.path for leaf in report.leaves}
    assert report.passed(_rtol(env)), str(report)


@pytest.mark.parametrize("scene", SCENES[1:], ids=[s[0] for s in SCENES[1:]])
@pytest.mark.parametrize("preset", ["euler", pytest.param("dopri5", marks=pytest.mark.slow)])  # dopri5: 5 to 14 s a scene
def test_every_scene_matches_finite_differences(scene, preset):
    name, make_env, actions, differentiable = scene
    env, report = _check(make_env, actions, differentiable, preset)
    assert report.passed(_rtol(env)), str(report)


@pytest.mark.slow  # about 8 s on 2 cores
@pytest.mark.parametrize("preset", ["tsit5"])
def test_forward_mode_jacfwd(preset):
    env, report = _check(_continuous, SCENES[0][2], True, preset, adjoint="forward", mode="forward")
    assert report.mode == "forward"
    assert report.passed(_rtol(env)), str(report)


@pytest.mark.slow  # 7.1 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_checkpoint_adjoint_refuses_forward_mode_and_names_the_fix():
    # JAX's own message names no fix (issue 29); a rollout and a single step (here with located
    # contacts) re-raise it naming with_adjoint. Refused when traced, so nothing is compiled.
    env = _continuous("tsit5")
    with pytest.raises(TypeError, match=r"with_adjoint\(env, 'forward'\)"):
        jax.jacfwd(lambda y0: ll.rollout(env, EnvState(y=y0, steps=jnp.zeros((), int)), jnp.zeros((2, 1)), key=jr.key(0))[0])(Y0)
    ball = ll.BouncingBall()
    state, _, _ = ball.reset(key=jr.key(0))
    with pytest.raises(TypeError, match=r"with_adjoint\(env, 'forward'\)"):
        jax.jacfwd(lambda y0: ball.step(EnvState(y=y0, steps=state.steps), jnp.zeros(2), key=jr.key(1))[0].y)(state.y)


@pytest.mark.slow  # about 12 s on 2 cores
def test_backsolve_is_an_approximation():
    # The continuous adjoint approximates the gradient of the continuous system, not of
    # the discrete solution the env computes: with Euler at dt = 0.02 it is off by
    # percents; with tight adaptive Tsit5 it agrees closely. (diffrax does not
    # differentiate t1 = dt under BacksolveAdjoint, so dt is left out.)
    euler_env, euler = _check(_continuous, SCENES[0][2], True, "euler", adjoint="backsolve", with_dt=False)
    tsit5_env, tsit5 = _check(_continuous, SCENES[0][2], True, "tsit5", adjoint="backsolve", with_dt=False)
    assert euler.max_relative_error > 1e-3, str(euler)
    assert tsit5.passed(ADAPTIVE_RTOL), str(tsit5)


def test_make_adjoint_names():
    assert isinstance(make_adjoint("checkpoint"), diffrax.RecursiveCheckpointAdjoint)
    assert isinstance(make_adjoint("forward"), diffrax.ForwardMode)
    assert isinstance(make_adjoint("backsolve"), diffrax.BacksolveAdjoint)
    with pytest.raises(ValueError, match="adjoint must be one of"):
        make_adjoint("adjoint")
    # The Integrator route: a scene built with an Integrator carries its adjoint.
    integrator = ll.make_integrator("tsit5", adjoint=diffrax.ForwardMode())
    assert isinstance(ll.make("CartPoleContinuous", solver=integrator).integrator.adjoint, diffrax.ForwardMode)


# ---- Non-smooth cases: what finite differences expose ----


def _episode_steps_and_loss(theta_dot0, env, horizon):
    """Steps before termination, and the sum of theta over the steps, with autoreset."""
    state = EnvState(y=jnp.stack([0.0, 0.0, 0.05, theta_dot0]), steps=jnp.zeros((), int))
    keys = jr.split(jr.key(1), horizon)

    def body(carry, key):
        state, alive, total = carry
        state, _, _, terminated, _, info = env.step(state, jnp.zeros((1,)), key=key)
        total = total + alive * info["final_observation"][2]
        alive = alive * (1.0 - terminated.astype(total.dtype))
        return (state, alive, total), None

    (_, alive, total), _ = jax.lax.scan(body, (state, jnp.ones(()), jnp.zeros(())), keys)
    return total


def test_termination_makes_finite_differences_meaningless():
    # A loss summed until the pole crosses the 12 degree threshold jumps when a change
    # of the initial angular velocity moves the crossing by one step. Autodiff gives the
    # derivative of the current branch; central differences straddling the jump give a
    # number of the order of jump / step, which is no derivative at all.
    env = ll.CartPoleContinuous()
    horizon = 40
    loss = jax.jit(lambda w: _episode_steps_and_loss(w, env, horizon))
    low, high = 0.0, 1.0  # terminates later at low, earlier at high: bisect the jump
    jump_low, jump_high = float(loss(low)), float(loss(high))
    for _ in range(60):
        middle = 0.5 * (low + high)
        if abs(float(loss(middle)) - jump_low) < abs(float(loss(middle)) - jump_high):
            low = middle
        else:
            high = middle
    at_jump = gradcheck(lambda w: loss(w), jnp.asarray(0.5 * (low + high)))
    smooth = gradcheck(lambda w: loss(w), jnp.asarray(0.25))
    assert smooth.passed(FIXED_STEP_RTOL), str(smooth)
    assert at_jump.max_relative_error > 0.5, str(at_jump)
    leaf = at_jump.leaves[0]
    assert abs(leaf.finite_difference) > 100 * abs(leaf.autodiff), str(at_jump)


def test_action_clip_has_no_derivative_at_the_limit():
    # At action = 1 the force saturates: the derivative from below is the slope, from
    # above it is zero. JAX's clip returns their average, which central differences
    # reproduce, and neither one-sided derivative.
    env = ll.make("CartPoleContinuous", reward="smooth")

    def final_x_dot(action):
        state = EnvState(y=Y0, steps=jnp.zeros((), int))
        next_state, _ = env.transition(state, jnp.reshape(action, (1,)), key=jr.key(0))
        return next_state.y[1]

    f = jax.jit(final_x_dot)
    h = 1e-6
    one = jnp.asarray(1.0)
    below = (float(f(one)) - float(f(one - h))) / h
    above = (float(f(one + h)) - float(f(one))) / h
    report = gradcheck(final_x_dot, one)
    assert below > 0.1 and abs(above) < 1e-9
    np.testing.assert_allclose(report.leaves[0].autodiff, 0.5 * below, rtol=1e-6)
    np.testing.assert_allclose(report.leaves[0].finite_difference, 0.5 * below, rtol=1e-6)
    # Past the limit the gradient is exactly zero: no signal for a learner.
    assert float(jax.grad(final_x_dot)(jnp.asarray(1.5))) == 0.0


# ---- The continuous adjoint where the dynamics are stiff ----
#
# One env step of dt = 1 with Kvaerno5, the stiff preset, from (2, 0): on the slow branch
# of the limit cycle, where the fast direction contracts at the rate mu (x^2 - 1) = 3 mu.
# BacksolveAdjoint reconstructs the state backwards in time, where that direction expands
# at the same rate: harmless at mu = 1, at mu = 1000 the backward solve exhausts its budget.


def _van_der_pol_final_state(mu, y0, env):
    """`x + v` after one env step from `y0`, with `mu` as the env's `mu`, and the solves' success."""
    env = eqx.tree_at(lambda e: e.dynamics.mu, env, mu)
    ys, infos = ll.rollout(env, EnvState(y=y0, steps=jnp.zeros((), dtype=int)), jnp.zeros((1, 1)), key=jr.key(0))
    return jnp.sum(ys[-1]), jnp.all(infos["solver_ok"])


def _both_cases(tree, env):
    # mu = 1 and mu = 1000 as one vmapped batch: one compilation serves both (Kvaerno5's
    # gradients take 10 s and more to compile), and each case has its own inputs, so the
    # gradient of the sum holds each case's gradient.
    values, solver_ok = jax.vmap(_van_der_pol_final_state, in_axes=(0, 0, None))(tree["mu"], tree["y0"], env)
    return jnp.sum(values), solver_ok


VAN_DER_POL_CASES = {"mu": jnp.array([1.0, 1000.0]), "y0": jnp.array([[2.0, 0.0], [2.0, 0.0]])}


@pytest.mark.slow
def test_plain_backsolve_adjoint_is_silently_wrong_on_stiff_van_der_pol():
    env = ll.make("VanDerPol", dt=1.0, solver="kvaerno5")
    # The default adjoint agrees with finite differences in both cases.
    report = gradcheck(lambda tree: _both_cases(tree, env)[0], VAN_DER_POL_CASES)
    assert report.passed(ADAPTIVE_RTOL), str(report)
    with pytest.warns(UserWarning, match="without throw=True"):
        plain = with_adjoint(env, diffrax.BacksolveAdjoint())
    gradient, solver_ok = eqx.filter_jit(jax.grad(_both_cases, has_aux=True))(VAN_DER_POL_CASES, plain)
    assert bool(jnp.all(solver_ok))  # every forward solve reports success
    relative_error = [
        max(
            np.linalg.norm(np.asarray(gradient[name][case]) - report[f"['{name}']"].finite_difference[case])
            / np.linalg.norm(report[f"['{name}']"].finite_difference[case])
            for name in ("mu", "y0")
        )
        for case in (0, 1)
    ]
    # mu = 1: the continuous adjoint approximates the gradient to about the solver's tolerance.
    assert relative_error[0] < ADAPTIVE_RTOL, relative_error
    # mu = 1000: the backward solve ran out of steps, which nothing reports; the gradient
    # is finite and wrong by orders of magnitude.
    assert all(bool(jnp.all(jnp.isfinite(leaf))) for leaf in jax.tree.leaves(gradient))
    assert relative_error[1] > 10, relative_error


@pytest.mark.slow
def test_named_backsolve_adjoint_raises_on_stiff_van_der_pol():
    # make_adjoint("backsolve") gives its backward solve throw=True: the exhausted budget
    # of the stiff case is raised instead of passed off as a gradient.
    env = with_adjoint(ll.make("VanDerPol", mu=1000.0, dt=1.0, solver="kvaerno5"), "backsolve")
    gradient = eqx.filter_jit(jax.grad(_van_der_pol_final_state, has_aux=True))
    with pytest.raises(Exception, match="maximum number of solver steps"):
        jax.block_until_ready(gradient(env.dynamics.mu, jnp.array([2.0, 0.0]), env))


@pytest.mark.parametrize("solver", ["euler", "rk4"])
def test_forward_mode_passes_one_constant_step_as_docs_gradients_says(solver):
    # docs/gradients.md: jax.jacfwd works through an env of one constant step per env step,
    # without with_adjoint; checked against central differences (float64).
    env = ll.make("CartPoleContinuous", solver=solver)
    state, _, _ = env.reset(key=jr.key(0))
    actions = jnp.full((10, 1), 0.3)

    def end_state(pole_mass):
        ys, _ = ll.rollout(eqx.tree_at(lambda e: e.dynamics.pole_mass, env, pole_mass), state, actions)
        return ys[-1]

    mass, h = env.dynamics.pole_mass, 1e-6
    central = (end_state(mass + h) - end_state(mass - h)) / (2 * h)
    np.testing.assert_allclose(jax.jacfwd(end_state)(mass), central, rtol=1e-6, atol=1e-9)


@pytest.mark.slow  # 2.7 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_forward_mode_through_an_adaptive_solver_names_the_forward_adjoint():
    env = ll.make("CartPoleContinuous", solver="tsit5")
    state, _, _ = env.reset(key=jr.key(0))
    end_state = lambda m: ll.rollout(eqx.tree_at(lambda e: e.dynamics.pole_mass, env, m), state, jnp.zeros((2, 1)))[0][-1]
    with pytest.raises(TypeError, match=r"with_adjoint\(env, 'forward'\)"):
        jax.jacfwd(end_state)(env.dynamics.pole_mass)
