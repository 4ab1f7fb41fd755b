"""Tolerances that the dtype can meet: a preset's follow the dtype it runs in, a user's below
the floor is raised with a warning naming it and the dtype (issue 43).

The tests run in float64 (conftest.py); the float32 runs are scoped with `jax.enable_x64(False)`.
"""

import contextlib
import warnings

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.integrate import tolerance_floors


@contextlib.contextmanager
def _float32():
    """float32 for the block, with JAX's standard promotion (conftest makes it strict)."""
    with jax.enable_x64(False), jax.numpy_dtype_promotion("standard"):
        yield


def _steps_and_states(make_env, steps=40):
    """Solver steps per env step (mean) and the states of a rollout of alternating pushes."""
    env = make_env()
    state, _, _ = env.reset(key=jax.random.key(0))
    step = jax.jit(lambda s, a: env.step(s, a, key=jax.random.key(1)))
    counts, states = [], []
    for action in np.arange(steps) % 2:
        state, _, _, _, _, info = step(state, jnp.asarray(action))
        assert bool(info["solver_ok"])
        counts.append(int(info["solver_steps"]))
        states.append(np.asarray(state.y, dtype=np.float64))
    return np.mean(counts), np.array(states)


SCENES_OF_THE_ISSUE = {
    "stiff (README)": lambda: ll.make("CartPole", pole_mass=0.2, joint_damping=300.0, solver="kvaerno5"),
    "tsit5": lambda: ll.make("CartPole", solver="tsit5"),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", SCENES_OF_THE_ISSUE)
def test_a_preset_in_float32_takes_about_the_steps_it_takes_in_float64(name):
    # Before the floors, the stiff example took 207 solver steps per env step in float32
    # against 21 in float64. The float32 states must still follow float64's closely.
    make_env = SCENES_OF_THE_ISSUE[name]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a preset's tolerances are raised silently
        with _float32():
            steps32, states32 = _steps_and_states(make_env)
    steps64, states64 = _steps_and_states(make_env)
    assert steps32 <= 1.5 * steps64, (steps32, steps64)
    scale = np.max(np.abs(states64), axis=0)
    assert np.max(np.abs(states32 - states64) / scale) < 1e-3


def test_a_users_tolerance_below_float32s_floor_warns_naming_it_and_the_dtype():
    controller = diffrax.PIDController(rtol=1e-10, atol=1e-12)
    eps = np.finfo(np.float32).eps
    with _float32():
        env = ll.make("CartPole", solver="tsit5", stepsize_controller=controller)
        state, _, _ = env.reset(key=jax.random.key(0))
        with pytest.warns(UserWarning) as record:
            _, _, _, _, _, info = env.step(state, 1, key=jax.random.key(1))
    assert bool(info["solver_ok"])
    message = str(record[0].message)
    assert "float32" in message and "rtol=1e-10" in message and "atol=1e-12" in message
    assert f"{100 * eps:.3g}" in message  # SciPy's solve_ivp floor for rtol, 100 eps


def test_in_float64_no_preset_and_no_ordinary_tolerance_is_touched():
    rtol_floor, atol_floor = tolerance_floors(jnp.float64, preset=True)
    for name, preset in ll.SOLVERS.items():
        controller = preset.make_controller()
        if isinstance(controller, diffrax.PIDController):
            assert controller.rtol >= rtol_floor and controller.atol >= atol_floor, name
    env = ll.make("CartPole", solver="tsit5", stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-12))
    state, _, _ = env.reset(key=jax.random.key(0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        env.step(state, 1, key=jax.random.key(1))


@pytest.mark.slow  # 3.9 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_gradcheck_refuses_float32_and_says_why():
    from lerax_like.gradients import gradcheck

    with _float32():
        with pytest.raises(RuntimeError, match="float32 finite differences carry rounding noise"):
            gradcheck(lambda p: jnp.sum(p["x"] ** 2), {"x": jnp.ones(2)})
