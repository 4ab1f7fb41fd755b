"""Bad input is refused by name, or reported and paid as a failure; never silently applied.

Functional API: an action of the wrong shape or dtype fails when the step is traced, with
a message naming the action and the space; an inadmissible action (a discrete one out of
range, a non-finite continuous one) is refused when concrete and reported in
`info["action_ok"]` when traced, ending the episode at the scene's worst reward. The
Gymnasium layer names `state` and Gymnasium's attribute names.
"""

import dataclasses
import re

import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest

import lerax_like as ll
from lerax_like.env import EnvState


def _start(env, key=jr.key(0)):
    return env.reset(key=key)[0]


@pytest.mark.parametrize("action", [2, -1, 7])
def test_out_of_range_discrete_action_is_refused_when_concrete(action):
    env = ll.CartPole()
    with pytest.raises(ValueError, match=rf"action {action} is not admissible in Discrete\(2\)"):
        env.step(_start(env), action, key=jr.key(1))


@pytest.mark.parametrize("action", [2, -1])
def test_out_of_range_discrete_action_is_a_failed_step_when_traced(action):
    env = ll.CartPole()
    state = _start(env)
    step = eqx.filter_jit(lambda env, state, action: env.advance(state, action, key=None))
    next_state, observation, reward, terminated, info = step(env, state, jnp.asarray(action))
    assert not bool(info["action_ok"])
    assert bool(terminated)
    assert float(reward) <= float(env.worst_reward)
    # The pre-step state, not the result of any action: both actions move the cart.
    np.testing.assert_array_equal(next_state.y, state.y)
    np.testing.assert_array_equal(observation, state.y)
    for valid in (0, 1):
        assert not np.array_equal(step(env, state, jnp.asarray(valid))[0].y, state.y)


def test_traced_actions_are_checked_one_by_one_under_vmap_and_scan():
    env = ll.MountainCar()
    state = _start(env)
    actions = jnp.array([0, 1, 2, 3, -1])
    _, _, reward, terminated, info = jax.vmap(lambda a: env.advance(state, a, key=None))(actions)
    np.testing.assert_array_equal(info["action_ok"], [True, True, True, False, False])
    np.testing.assert_array_equal(terminated, [False, False, False, True, True])
    np.testing.assert_array_equal(reward[3:], [float(env.worst_reward)] * 2)
    _, infos = ll.rollout(env, state, jnp.array([2, 2, 5, 0]))
    np.testing.assert_array_equal(infos["action_ok"], [True, True, False, True])
    assert bool(infos["terminated"][2])


@pytest.mark.parametrize("scene", [ll.CartPoleContinuous, ll.Pendulum, ll.MountainCarContinuous])
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_continuous_action(scene, value):
    env = scene()
    state = _start(env)
    with pytest.raises(ValueError, match=r"action \[(nan|inf|-inf)\] is not admissible in Box\(.*finite"):
        env.step(state, jnp.array([value]), key=jr.key(1))
    next_state, _, reward, terminated, info = eqx.filter_jit(lambda env, a: env.advance(state, a, key=None))(
        env, jnp.array([value])
    )
    assert not bool(info["action_ok"]) and bool(terminated)
    assert float(reward) <= float(env.worst_reward)
    np.testing.assert_array_equal(next_state.y, state.y)


def test_out_of_bounds_finite_continuous_action_is_clipped_as_in_gymnasium():
    env = ll.CartPoleContinuous()
    state = _start(env)
    far = env.advance(state, jnp.array([5.0]), key=None)
    edge = env.advance(state, jnp.array([1.0]), key=None)
    assert bool(far[4]["action_ok"])
    np.testing.assert_array_equal(far[0].y, edge[0].y)


@pytest.mark.parametrize(
    "scene, action, expected",
    [
        (ll.CartPole, 0.5, r"action must be an integer scalar \(shape \(\), an integer dtype\) of Discrete\(2\), got shape \(\) and dtype float"),
        (ll.CartPole, jnp.array([0, 1]), r"action must be an integer scalar .* of Discrete\(2\), got shape \(2,\)"),
        (ll.CartPole, True, r"action must be an integer scalar .* dtype bool"),
        (ll.CartPoleContinuous, jnp.ones(2), r"action must be a real array of shape \(1,\) of Box\(.*\), got shape \(2,\)"),
        (ll.Pendulum, jnp.ones((1, 1)), r"action must be a real array of shape \(1,\) of Box\(.*\), got shape \(1, 1\)"),
        (ll.NLinkPendulum, jnp.ones(2), r"action must be a real array of shape \(3,\) of Box\(.*\), got shape \(2,\)"),
        (ll.CartPoleContinuous, "left", r"action must be an element of Box"),
    ],
)
def test_action_of_wrong_shape_or_dtype_fails_at_trace_time_naming_it(scene, action, expected):
    env = scene()
    state = _start(env)
    with pytest.raises(TypeError, match=expected):
        env.step(state, action, key=jr.key(1))
    if not isinstance(action, str):
        # Under jit too, when tracing (before anything runs).
        with pytest.raises(TypeError, match=expected):
            eqx.filter_jit(lambda env, state, action: env.step(state, action, key=jr.key(1)))(env, state, jnp.asarray(action))


def test_scalar_action_of_a_one_element_box_is_accepted():
    env = ll.Pendulum()
    state = _start(env)
    scalar = env.advance(state, jnp.asarray(0.7), key=None)
    vector = env.advance(state, jnp.array([0.7]), key=None)
    np.testing.assert_array_equal(scalar[0].y, vector[0].y)


@pytest.mark.parametrize("scene", [ll.CartPole, ll.Pendulum])
def test_state_of_wrong_shape_is_refused_by_name(scene):
    env = scene()
    n = _start(env).y.shape[0]
    wrong = EnvState(y=jnp.zeros(n + 1), steps=jnp.zeros((), dtype=int))
    action = env.action_space.sample(key=jr.key(0))
    with pytest.raises(ValueError, match=rf"state.y must have shape \({n},\) \(the state of {scene.__name__}\), got shape \({n + 1},\)"):
        env.step(wrong, action, key=jr.key(1))
    with pytest.raises(ValueError, match=r"state.y must have shape"):
        ll.rollout(env, wrong, action[None])


def test_gymnasium_state_of_wrong_shape_is_refused_by_name():
    env = gymnasium.make("lerax_like/CartPole-v1")
    with pytest.raises(ValueError, match=re.escape("state must have shape (4,) (CartPole-v1's state), got shape (2,)")):
        env.unwrapped.state = [0, 0]
    with pytest.raises(TypeError, match=r"state must be a real array of shape \(4,\)"):
        env.unwrapped.state = ["a", "b", "c", "d"]
    vector = gymnasium.make_vec("lerax_like/Pendulum-v1", 3, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match=re.escape("state must have shape (2, 3) (state size, num_envs), got shape (3, 2)")):
        vector.unwrapped.state = np.zeros((3, 2))


def _array_fields(module):
    return [field.name for field in dataclasses.fields(module) if eqx.is_inexact_array(getattr(module, field.name))]


@pytest.mark.parametrize("name", list(ll.SCENES))
def test_non_numeric_parameters_are_refused_by_name(name):
    scene = ll.SCENES[name]
    default = scene()
    # The dynamics' parameters, given flat as Gymnasium users give them, and the task's.
    names = [n for n in _array_fields(default.dynamics) if n not in _array_fields(default)] + _array_fields(default)
    assert names
    for parameter in names:
        with pytest.raises(TypeError, match=rf"^{parameter} must be a real number, got 'heavy'"):
            ll.make(scene, **{parameter: "heavy"})


def test_non_numeric_parameter_through_gymnasium_make_is_refused_by_name():
    with pytest.raises(TypeError, match="pole_mass must be a real number, got 'heavy'"):
        gymnasium.make("lerax_like/CartPole-v1", pole_mass="heavy")
    with pytest.raises(TypeError, match="gravity must be a real number, got 'strong'"):
        gymnasium.make("lerax_like/Pendulum-v1", g="strong")


def test_gymnasium_attribute_writes_are_checked_by_gymnasiums_name():
    env = gymnasium.make("lerax_like/CartPole-v1")
    with pytest.raises(ValueError, match=r"masscart \(the scene's dynamics.cart_mass\): cart_mass must be finite and > 0"):
        env.unwrapped.masscart = -1.0
    with pytest.raises(TypeError, match=r"gravity must be a real number, got 'strong'"):
        env.set_wrapper_attr("gravity", "strong")
    car = gymnasium.make("lerax_like/MountainCar-v0")
    with pytest.raises(ValueError, match=r"min_position .*min_position must be < max_position"):
        car.unwrapped.min_position = 1.0
    assert env.get_wrapper_attr("masscart") == 1.0 and car.get_wrapper_attr("min_position") == -1.2


def test_jax_jit_of_a_bound_step_says_to_use_filter_jit():
    env = ll.CartPole()
    state = _start(env)
    with pytest.raises(TypeError, match=r"CartPole holds arrays .* cannot be hashed.*use eqx.filter_jit\(env.step\)"):
        jax.jit(env.step)(state, 1, key=jr.key(1))
    # What it advises works, and a scene without arrays (the static part) still hashes.
    eqx.filter_jit(env.step)(state, 1, key=jr.key(1))
    hash(eqx.partition(env, eqx.is_array)[1])
