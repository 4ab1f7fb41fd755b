"""`Integrator.integrate` against `diffrax.diffeqsolve` called directly.

One constant step is taken with the solver's own `step`, outside `diffeqsolve`'s loop
(it is the hot path of every fixed-step env). These tests hold it to what `diffeqsolve`
computes from the same term, solver and step: state, solver info and gradients.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import pytest

import lerax_like as ll
from lerax_like.integrate import ProjectedODETerm

from conftest import tree_allclose


# One solver of each kind diffrax steps differently (Heun, midpoint and Ralston are
# explicit Runge-Kutta methods like RK4).
FIXED_STEP_PRESETS = ("euler", "rk4", "semi_implicit_euler")
# Embedded and implicit methods run with a constant step too (the implicit ones then get
# explicit root-finder tolerances from `make_integrator`).
CONSTANT_STEP_OF_ADAPTIVE = ("tsit5", "implicit_euler")


def _reference(integrator, scene, y0, u):
    """One step of `scene`'s dynamics by `diffeqsolve` itself, projected as `integrate` does."""
    term = ProjectedODETerm(
        scene.dynamics.vector_field, projection=scene.project, velocity_indices=scene.dynamics.velocity_indices
    )
    solution = diffrax.diffeqsolve(
        term, integrator.solver, t0=0.0, t1=scene.dt, dt0=scene.dt, y0=y0, args=u,
        stepsize_controller=diffrax.ConstantStepSize(), max_steps=1,
    )
    return scene.project(solution.ys[-1])


def _integrate(integrator, scene, y0, u):
    y1, info = integrator.integrate(
        scene.dynamics.vector_field, y0, u, scene.dt,
        projection=scene.project, velocity_indices=scene.dynamics.velocity_indices,
    )
    return y1, info


def _integrator(preset):
    if preset in CONSTANT_STEP_OF_ADAPTIVE:
        return ll.make_integrator(preset, diffrax.ConstantStepSize())
    return ll.make_integrator(preset)


# Every preset on the cart-pole; the pendulum's projected step with the solver that
# reproduces Gymnasium and with one that does not know of the projection.
# The embedded and implicit ones (10 to 12 s each on 2 cores) run in CI only.
CASES = [(preset, ll.CartPoleContinuous) for preset in FIXED_STEP_PRESETS] + [
    pytest.param(preset, ll.CartPoleContinuous, marks=pytest.mark.slow) for preset in CONSTANT_STEP_OF_ADAPTIVE
] + [
    ("semi_implicit_euler", ll.Pendulum),
    ("rk4", ll.Pendulum),
]


@pytest.mark.parametrize(("preset", "scene_cls"), CASES)
@pytest.mark.slow  # up to 6.3 s a case of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_one_constant_step_is_diffeqsolves_step(preset, scene_cls):
    scene = scene_cls()
    integrator = _integrator(preset)
    # Pendulum's speed clip is active from this start: the projection is exercised.
    y0 = jnp.array([0.3, -0.2, 0.1, 0.4]) if scene_cls is ll.CartPoleContinuous else jnp.array([2.5, 7.9])
    u = scene.physical_input(jnp.array([0.7]))

    def loss(step, scene, y0, u):
        return jnp.sum(jnp.sin(step(integrator, scene, y0, u)))

    @eqx.filter_jit
    def both(scene, y0, u):
        # Gradients with respect to the physical parameters (the scene's floating-point
        # leaves: its episode limit is an integer leaf), the start and the input.
        parameters, rest = eqx.partition(scene, eqx.is_inexact_array)

        def gradient(step):
            def of(parameters, y0, u):
                return loss(step, eqx.combine(parameters, rest), y0, u)

            return jax.grad(of, argnums=(0, 1, 2))(parameters, y0, u)

        ours = (_integrate(integrator, scene, y0, u), gradient(lambda *a: _integrate(*a)[0]))
        return ours, (_reference(integrator, scene, y0, u), gradient(_reference))

    ((y1, info), gradient), (reference, reference_gradient) = both(scene, y0, u)
    assert tree_allclose(y1, reference, rtol=1e-14, atol=1e-15)
    assert bool(info["solver_ok"])
    assert int(info["solver_steps"]) == 1 and int(info["solver_rejected_steps"]) == 0
    assert tree_allclose(gradient, reference_gradient, rtol=1e-12, atol=1e-14)


def test_a_non_finite_single_step_is_reported():
    scene = ll.CartPoleContinuous()
    y1, info = _integrate(ll.make_integrator("euler"), scene, jnp.array([0.0, jnp.inf, 0.1, 0.0]), jnp.array([1.0]))
    assert not bool(info["solver_ok"])


@pytest.mark.parametrize(
    ("integrator", "steps"),
    [
        (ll.make_integrator("rk4", substeps=3), 3),
        (ll.make_integrator("rk4", adjoint=diffrax.BacksolveAdjoint(throw=True)), 1),
        (ll.make_integrator("rk4", diffrax.StepTo(ts=jnp.array([0.0, 0.01, 0.02]))), 2),
    ],
    ids=["substeps", "backsolve", "step_to"],
)
def test_other_fixed_step_settings_still_go_through_diffeqsolve(integrator, steps):
    # Several steps, another adjoint or another controller: `diffeqsolve` runs them,
    # and the result is still `steps` equal steps of the method over [0, dt].
    scene = ll.CartPoleContinuous()
    y0 = jnp.array([0.3, -0.2, 0.1, 0.4])
    u = scene.physical_input(jnp.array([0.7]))
    y1, info = _integrate(integrator, scene, y0, u)
    assert int(info["solver_steps"]) == steps
    reference = diffrax.diffeqsolve(
        diffrax.ODETerm(scene.dynamics.vector_field), integrator.solver, t0=0.0, t1=scene.dt,
        dt0=scene.dt / steps, y0=y0, args=u, max_steps=steps,
    ).ys[-1]
    assert tree_allclose(y1, reference, rtol=1e-14, atol=1e-15)


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
@pytest.mark.parametrize("preset", ["rk4", "tsit5"])
def test_forward_mode_passes_through_one_runge_kutta_step(preset):
    # diffeqsolve switches a Runge-Kutta method's checkpointed stage loop to a plain one
    # for `ForwardMode`; the direct step must too, or `jax.jacfwd` fails.
    scene = ll.CartPoleContinuous()
    y0 = jnp.array([0.3, -0.2, 0.1, 0.4])
    u = scene.physical_input(jnp.array([0.7]))
    forward = _integrator(preset).with_adjoint(diffrax.ForwardMode())

    jacobian = jax.jit(jax.jacfwd(lambda y: _integrate(forward, scene, y, u)[0]))(y0)
    reference = jax.jit(jax.jacrev(lambda y: _reference(forward, scene, y, u)))(y0)
    assert tree_allclose(jacobian, reference, rtol=1e-12, atol=1e-14)
