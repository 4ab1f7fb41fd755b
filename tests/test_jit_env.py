"""An env is a valid argument of plain `jax.jit`, for every scene, every preset and a user's controller.

`eqx.filter_jit` holds every non-array leaf static; plain `jax.jit` (what a JAX RL
trainer calls) traces every leaf, so an env must have no leaf but arrays. The step it
compiles must be the one `eqx.filter_jit` compiles.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import optimistix
import pytest

import lerax_like as ll


def _non_array_leaves(tree):
    return [jax.tree_util.keystr(path) for path, leaf in jax.tree_util.tree_leaves_with_path(tree)
            if not eqx.is_array(leaf)]


def _user_controller():
    # A controller of the user's own, with a function of its own (the norm) and a tolerance
    # given as an array (a traced leaf: one compilation serves every value).
    return diffrax.PIDController(rtol=jnp.asarray(1e-7), atol=1e-10, norm=optimistix.max_norm, pcoeff=0.2, icoeff=0.4)


@pytest.mark.parametrize("solver", ll.SOLVERS.names)
@pytest.mark.parametrize("name", sorted(ll.SCENES))
def test_every_leaf_of_an_env_is_an_array(name, solver):
    env = ll.make(name, solver=solver)
    assert _non_array_leaves(env) == []
    # The physical parameters are still leaves, so still differentiable.
    assert jax.tree.leaves(env.dynamics), name


def test_a_users_controller_leaves_only_arrays_and_keeps_its_settings():
    controller = _user_controller()
    assert _non_array_leaves(controller)  # as given, it holds a function and Python numbers
    env = ll.make("CartPoleContinuous", solver="tsit5", stepsize_controller=controller)
    assert _non_array_leaves(env) == []
    held = env.integrator.stepsize_controller
    assert held.norm is optimistix.max_norm and (held.atol, held.pcoeff, held.icoeff) == (1e-10, 0.2, 0.4)
    assert held.rtol is controller.rtol  # the array is the env's leaf, not a copy
    # A traced tolerance: a different rtol reuses the compiled step.
    assert any(leaf is controller.rtol for leaf in jax.tree.leaves(env))


def _compare_jit_with_filter_jit(env, key):
    action = env.action_space.sample(key=jr.fold_in(key, 1))
    step_key = jr.fold_in(key, 2)

    def step(env, state, action):
        return env.step(state, action, key=step_key)

    try:
        # `reset` traces a step for its info's structure, so a refused pairing is refused here.
        state, _, _ = env.reset(key=jr.fold_in(key, 0))
        filtered = eqx.filter_make_jaxpr(step)(env, state, action)[0]
    except ValueError as error:
        # A pairing refused when traced (semi-implicit Euler on dynamics that declare no
        # velocities): plain jit refuses it with the same message.
        with pytest.raises(ValueError, match="velocity_indices"):
            state = env.initial(key=jr.fold_in(key, 0))
            jax.jit(step)(env, state, action)
        assert "velocity_indices" in str(error)
        return
    # The program plain jit traces is the one `eqx.filter_jit` traces, equation for equation
    # (a leaf that were not an array would be a traced input of the one and a constant of the
    # other), so the two compile alike: plain jit's is compiled and run, once.
    traced = jax.jit(step).trace(env, state, action)
    assert str(traced.jaxpr) == str(filtered)
    plain = traced.lower().compile()(env, state, action)
    assert bool(plain[-1]["solver_ok"]) and bool(jnp.all(jnp.isfinite(plain[1])))


# Compiling is what costs here: all 169 pairs of scene and preset (the test scene included)
# took about 350 s of one worker's time. The leaf test above covers every pair; the pairs compiled cover every scene
# with an adaptive explicit preset, an implicit one and semi-implicit Euler (whose refusal
# depends on the scene), and every preset on a scene with located impacts and on one with a
# discrete action.
_COMPILED_PAIRS = sorted(
    {(name, solver) for name in ll.SCENES for solver in ("tsit5", "kvaerno5", "semi_implicit_euler")}
    | {(name, solver) for name in ("BouncingBall", "CartPole") for solver in ll.SOLVERS.names}
)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "solver"), _COMPILED_PAIRS)
def test_plain_jit_of_a_step_runs_and_matches_filter_jit(name, solver):
    _compare_jit_with_filter_jit(ll.make(name, solver=solver), jr.key(7))


@pytest.mark.parametrize("adjoint", ["checkpoint", "forward", "backsolve"])
def test_every_leaf_is_an_array_whatever_the_adjoint(adjoint):
    env = ll.with_adjoint(ll.make("CartPoleContinuous", solver="tsit5"), adjoint)
    assert _non_array_leaves(env) == []
    assert isinstance(env.integrator.adjoint, type(ll.make_adjoint(adjoint)))


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_plain_jit_with_a_users_controller_and_a_gradient_through_it():
    env = ll.make("CartPoleContinuous", solver="tsit5", stepsize_controller=_user_controller())
    _compare_jit_with_filter_jit(env, jr.key(3))
    state, _, _ = env.reset(key=jr.key(4))
    action = jnp.array([0.5])

    def position(env):
        return env.step(state, action, key=jr.key(5))[0].y[0]

    # Parameters stay differentiable leaves under plain jit: jax.grad over the env.
    gradient = jax.jit(jax.grad(position, allow_int=True))(env)
    assert jnp.isfinite(gradient.dynamics.cart_mass) and gradient.dynamics.cart_mass != 0
