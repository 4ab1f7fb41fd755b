"""Failures are reported, never silent.

A step whose integration fails (non-finite state, exhausted step budget) or whose
observation or reward overflows sets `info["solver_ok"] = False` and terminates the
episode; nothing non-finite is returned; the autoreset starts a fresh episode; all of it
under jit and vmap.
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import quick_unless_hybrid
from hypothesis import given, settings, strategies as st

import lerax_like as ll


def _run(env, y0, actions, key):
    """`env.step` over `actions` from `y0`, keeping everything a test may check."""
    state = ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int))

    def body(state, inputs):
        action, step_key = inputs
        next_state, observation, reward, terminated, truncated, info = env.step(state, action, key=step_key)
        # The raw solve from the pre-step state, outside the env's safety net.
        raw, _ = env.integrator.integrate(
            env.physics.vector_field, state.y, env.physical_input(action), env.dt
        )
        record = dict(
            observation=observation, reward=reward, terminated=terminated, truncated=truncated,
            solver_ok=info["solver_ok"], final_observation=info["final_observation"],
            steps=next_state.steps, raw_finite=jnp.all(jnp.isfinite(raw)),
        )
        return next_state, record

    keys = jax.random.split(key, actions.shape[0])
    return jax.lax.scan(body, state, (actions, keys))[1]


_run_jit = eqx.filter_jit(_run)


def test_explicit_euler_divergence_is_flagged_and_ends_the_episode():
    env = ll.make("CartPoleContinuous",
        dt=0.5, solver="euler", theta_threshold_radians=jnp.inf, x_threshold=jnp.inf, max_episode_steps=None
    )
    y0 = jnp.array([[0.0, 0.0, 0.1, 0.0], [0.0, 0.0, -0.05, 0.0], [0.01, 0.0, 0.0, 0.02]])
    actions = jnp.ones((len(y0), 300, 1))
    keys = jax.random.split(jax.random.key(0), len(y0))
    record = eqx.filter_jit(jax.vmap(_run, in_axes=(None, 0, 0, 0)))(env, y0, actions, keys)
    record = jax.tree.map(np.asarray, record)
    failed = ~record["solver_ok"]
    # Euler at dt = 0.5 diverges (within ~100 steps; again after some autoresets).
    assert np.all(failed.sum(axis=1) >= 1)
    # Flagged exactly when the solve met a non-finite state...
    np.testing.assert_array_equal(failed, ~record["raw_finite"])
    # ...and the episode ends on exactly those steps (no task termination: bounds are inf).
    np.testing.assert_array_equal(record["terminated"], failed)
    assert not record["truncated"].any()
    # Nothing non-finite leaves the env.
    for name in ("observation", "reward", "final_observation"):
        assert np.all(np.isfinite(record[name])), name
    # The autoreset starts a fresh episode: step counter 0, state in the start box.
    assert np.all(record["steps"][failed] == 0)
    assert np.all(np.abs(record["observation"][failed]) <= 0.05)


class _NaNWindow(ll.AbstractDynamics):
    """Decays, except that the field is NaN for `0.25 <= t < 0.35`, then decays again."""

    velocity_indices = None

    def vector_field(self, t, y, u):
        inside = (t >= 0.25) & (t < 0.35)
        return jnp.where(inside, jnp.nan, -y)


@pytest.mark.slow  # 2.6 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_nan_mid_trajectory_under_constant_step_size_is_caught():
    # diffrax's ConstantStepSize never looks at the state. A NaN met at an inner step is
    # still in the end state: a Runge-Kutta step is y + h * sum(b_i k_i) and NaN (or
    # 0 * inf) absorbs every later operation, so checking the end state is enough.
    dynamics = _NaNWindow()
    for solver in ("euler", "heun", "rk4"):
        integrator = ll.make_integrator(solver, substeps=10)
        y1, info = integrator.integrate(dynamics.vector_field, jnp.ones(2), jnp.zeros(1), 1.0)
        assert not bool(info["solver_ok"]), solver
        assert int(info["solver_steps"]) == 10
    # The same field away from the window is fine.
    y1, info = ll.make_integrator("euler", substeps=10).integrate(dynamics.vector_field, jnp.ones(2), jnp.zeros(1), 0.2)
    assert bool(info["solver_ok"])


@pytest.mark.slow  # 2.6 s of one worker at 4ff5f8c (docs/testing.md): CI's, not the quick loop's
def test_budget_exhaustion_under_vmap_is_reported_per_env():
    # Parameters traced under vmap: one compile for both envs; the stiff one fails.
    make = lambda mu: ll.make("VanDerPol", mu=mu, dt=1.0, solver=ll.make_integrator("tsit5", max_steps=256))
    envs = eqx.filter_vmap(make)(jnp.array([1.0, 1000.0]))
    y0 = jnp.array([[2.0, 0.0], [2.0, 0.0]])
    actions = jnp.zeros((2, 3, 1))
    keys = jax.random.split(jax.random.key(0), 2)
    record = eqx.filter_jit(eqx.filter_vmap(_run))(envs, y0, actions, keys)
    ok = np.asarray(record["solver_ok"])
    assert ok[0].all() and not ok[1].any()
    np.testing.assert_array_equal(np.asarray(record["terminated"]), ~ok)
    assert np.all(np.isfinite(np.asarray(record["observation"])))


class _Decay(ll.AbstractDynamics):
    velocity_indices = None

    def vector_field(self, t, y, u):
        return -y + u


class _ExponentialReward(ll.AbstractEnv):
    """A test scene whose finite states can overflow in the reward: exp(x)."""

    stochastic = False

    dynamics: _Decay
    integrator: ll.Integrator
    dt: jax.Array
    max_episode_steps: None = None

    @property
    def action_space(self):
        return ll.Box(-1.0, 1.0, (1,))

    @property
    def observation_space(self):
        return ll.Box(-jnp.inf, jnp.inf, (1,))

    @property
    def initial_bounds(self):
        return jnp.zeros(1), jnp.zeros(1)

    def physical_input(self, action):
        return action

    def observation(self, state, *, key):
        return state.y

    def reward(self, state, action, next_state, *, key):
        return jnp.exp(next_state.y[0])

    @property
    def worst_reward(self):
        return jnp.zeros(())

    def terminal(self, state, *, key):
        return jnp.asarray(False)


def test_overflowing_reward_is_flagged_and_replaced():
    # A finite state (x = 1e3) whose reward overflows: the last line of defence.
    env = _ExponentialReward(_Decay(), ll.make_integrator("euler"), jnp.asarray(1e-3))
    record = _run_jit(env, jnp.array([1e3]), jnp.zeros((2, 1)), jax.random.key(0))
    assert not bool(record["solver_ok"][0]) and bool(record["raw_finite"][0])
    assert bool(record["terminated"][0])
    assert float(record["reward"][0]) == float(env.worst_reward) == 0.0
    assert np.all(np.isfinite(np.asarray(record["final_observation"])))
    # The autoreset put the env at x = 0, where the reward is 1 again.
    assert bool(record["solver_ok"][1]) and float(record["reward"][1]) == 1.0


# --- properties over the documented valid ranges -------------------------------------

def _log_uniform(low, high):
    return st.floats(np.log10(low), np.log10(high)).map(lambda e: float(10.0**e))


_cartpole_parameters = st.fixed_dictionaries(
    dict(
        pole_mass=_log_uniform(1e-6, 1e3),
        half_length=_log_uniform(5e-3, 50.0),
        cart_mass=_log_uniform(1e-4, 1e3),
        force_mag=_log_uniform(1e-3, 1e4),
        dt=_log_uniform(1e-3, 0.5),
        joint_damping=st.sampled_from([0.0, 1.0, 300.0]),
        end_stop_stiffness=st.sampled_from([0.0, 1e3, 1e6]),
        end_stop_damping=st.sampled_from([0.0, 10.0]),
    )
)
_cartpole_states = st.tuples(
    st.floats(-3.0, 3.0), st.floats(-10.0, 10.0), st.floats(-np.pi, np.pi), st.floats(-10.0, 10.0)
)
_two_steps = eqx.filter_jit(lambda env, y0, actions, key: _run(env, y0, actions, key))


@pytest.mark.slow  # 5.8 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
@settings(max_examples=12, deadline=None, derandomize=True)
@given(_cartpole_parameters, _cartpole_states, st.floats(-1.0, 1.0), st.sampled_from(["tsit5", "euler"]))
def test_cartpole_steps_are_finite_and_flags_consistent(parameters, y0, action, solver):
    integrator = ll.make_integrator(solver, max_steps=256 if solver == "tsit5" else None)
    env = ll.make("CartPoleContinuous",
        **parameters, solver=integrator, reward="smooth", max_episode_steps=2, track_limit=2.4
    )
    record = _two_steps(env, jnp.asarray(y0), jnp.full((2, 1), action), jax.random.key(0))
    record = jax.tree.map(np.asarray, record)
    for name in ("observation", "reward", "final_observation"):
        assert np.all(np.isfinite(record[name])), name
    failed = ~record["solver_ok"]
    # A non-finite solve is always flagged (a finite one may fail too: budget, overflow).
    assert np.all(failed[~record["raw_finite"]])
    assert np.all(record["terminated"][failed])
    done = record["terminated"] | record["truncated"]
    assert np.all(record["steps"][done] == 0)
    # Without a reset in between, the step counter counts; the second step truncates.
    assert record["steps"][0] == (0 if done[0] else 1)
    assert record["truncated"][1] == (not done[0])


@settings(max_examples=8, deadline=None, derandomize=True)
@given(st.floats(0.0, 1e3), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-1.0, 1.0))
def test_van_der_pol_steps_are_finite_and_flags_consistent(mu, x, v, action):
    env = ll.make("VanDerPol", mu=mu, dt=0.5, solver=ll.make_integrator("tsit5", max_steps=256))
    record = _two_steps(env, jnp.array([x, v]), jnp.full((2, 1), action), jax.random.key(0))
    record = jax.tree.map(np.asarray, record)
    for name in ("observation", "reward", "final_observation"):
        assert np.all(np.isfinite(record[name])), name
    failed = ~record["solver_ok"]
    np.testing.assert_array_equal(record["terminated"], failed)
    if mu <= 1.0:
        # Not stiff: a modest budget always suffices.
        assert not failed.any()


def test_gymnasium_layer_flags_divergence_and_returns_finite_float32():
    import gymnasium

    # Euler at dt = 0.5 diverges; the float64 state overflows float32 long before it
    # overflows itself: the float32 observation must still be finite, and flagged.
    env = gymnasium.make("lerax_like/CartPole-v1", dt=0.5, theta_threshold_radians=np.inf, x_threshold=np.inf)
    action = 1
    env.reset(seed=0)
    for _ in range(400):
        observation, reward, terminated, truncated, info = env.step(action)
        assert np.all(np.isfinite(observation)) and np.isfinite(reward)
        assert terminated == (not info["solver_ok"])
        if terminated:
            break
    assert terminated and not info["solver_ok"]


# -- Failures pay nothing an agent wants, for every registered scene ------------------------
#
# Each scene declares `worst_reward`, a lower bound of its regular rewards, and a failed
# step pays it. Checked for every scene of `lerax_like.SCENES`, in every variant of its
# static options (`CartPole(sutton_barto_reward=True)`, `DoubleCartPole(task="swing_up")`):
# regular rewards over random states and actions never fall below the bound, and a forced
# failure pays at most the bound, terminates and returns a finite observation.


def _variants():
    import dataclasses

    for name, scene in ll.SCENES.items():
        yield name, {}
        for field in dataclasses.fields(scene):
            for choice in field.metadata.get("choices") or ():
                if choice != field.default:
                    yield name, {field.name: choice}


VARIANTS = [
    quick_unless_hybrid(name, options, id=f"{name}-{'-'.join(f'{k}={v}' for k, v in options.items()) or 'default'}")
    for name, options in _variants()
]


def _random_actions(env, key, shape):
    return jax.vmap(lambda k: env.action_space.sample(key=k))(jax.random.split(key, np.prod(shape))).reshape(
        *shape, *env.action_space.shape
    )


# One compiled step per scene variant serves every test below: the regular steps, one at a
# time, and the three forced failures (same structure and shapes). A vmapped step for the
# regular ones compiled a second, larger program per variant (an adaptive solve with located
# events batched: 25 to 38 s of a loaded machine each for BouncingBall, the walkers and
# SlidingBlock), for a claim about each step, not about batching.
_advance = eqx.filter_jit(lambda env, state, action, key: env.advance(state, action, key=key))


@eqx.filter_jit
def _regular_inputs(env, key, num_states=256):
    """Random states and actions, and a key for each step."""
    low, high = env.initial_bounds
    wide_key, start_key, action_key, step_key = jax.random.split(key, 4)
    # States far from the usual starts (up to 10 units each way), made admissible by the
    # scene's own projection, and the usual starts.
    wide = (low + high) / 2 + jax.random.uniform(wide_key, (num_states, low.size), minval=-10.0, maxval=10.0)
    wide = jax.vmap(env.project)(wide)
    usual = jax.vmap(lambda k: env.initial(key=k).y)(jax.random.split(start_key, num_states))
    states = jnp.concatenate([wide, usual])
    actions = _random_actions(env, action_key, (states.shape[0],))
    return states, actions, jax.random.split(step_key, states.shape[0])


def _regular_rewards(env, key):
    """Rewards of one step from random states under random actions, with whether each was regular."""
    states, actions, keys = _regular_inputs(env, key)
    rewards, regular = [], []
    for y, action, step_key in zip(states, actions, keys):
        state = ll.EnvState(y=y, steps=jnp.zeros((), dtype=int))
        _, _, reward, _, info = _advance(env, state, action, step_key)
        rewards.append(reward)
        regular.append(info["solver_ok"] & info["action_ok"])
    return np.asarray(rewards), np.asarray(regular)


@pytest.mark.parametrize("name, options", VARIANTS)
@pytest.mark.slow  # up to 4.3 s a case of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_worst_reward_bounds_every_regular_reward(name, options):
    env = ll.make(name, **options)
    rewards, regular = _regular_rewards(env, jax.random.key(0))
    assert regular.mean() > 0.5, "most sampled steps should be regular"
    worst = float(env.worst_reward)
    assert np.isfinite(worst)
    assert rewards[regular].min() >= worst, (rewards[regular].min(), worst)


# The failures below are built with `full_like` from the regular values, so that they keep their
# dtype and (not weak) type: a weakly typed array would compile `_advance` again for its case.


def _inadmissible_action(env, action):
    space = env.action_space
    return jnp.full_like(action, space.n if isinstance(space, ll.Discrete) else jnp.nan)


def _nan_dynamics(env):
    dynamics = jax.tree.map(lambda leaf: jnp.full_like(leaf, jnp.nan) if eqx.is_array(leaf) else leaf, env.dynamics)
    return eqx.tree_at(lambda e: e.dynamics, env, dynamics)


def _overflowing(env, state):
    # A state of 1e300 moved by its velocity of 1e300 for 1e10 time units overflows.
    return eqx.tree_at(lambda e: e.dt, env, jnp.full_like(env.dt, 1e10)), ll.EnvState(y=jnp.full_like(state.y, 1e300), steps=state.steps)


FAILURES = ("inadmissible action", "nan dynamics", "overflow")


@pytest.mark.parametrize("failure", FAILURES)
@pytest.mark.parametrize("name, options", VARIANTS)
def test_a_forced_failure_pays_at_most_the_worst_reward(name, options, failure):
    env = ll.make(name, **options)
    state = env.reset(key=jax.random.key(3))[0]
    action = env.action_space.sample(key=jax.random.key(4))
    if failure == "inadmissible action":
        action = _inadmissible_action(env, action)
    elif failure == "nan dynamics":
        env = _nan_dynamics(env)
    elif env.projects_state():
        pytest.skip("the scene clips its state, which cannot overflow")
    else:
        env, state = _overflowing(env, state)
    worst = float(env.worst_reward)
    next_state, observation, reward, terminated, info = _advance(env, state, action, jax.random.key(5))
    # The failure happened, and was reported.
    if failure == "inadmissible action":
        assert not bool(info["action_ok"])
    else:
        assert not bool(info["solver_ok"])
    assert float(reward) <= worst
    assert bool(terminated)
    assert np.all(np.isfinite(np.asarray(observation)))
    np.testing.assert_array_equal(next_state.y, state.y)


@pytest.mark.slow  # 3.4 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_overflow_covers_every_scene_that_does_not_clip_its_state():
    # The overflow case above runs for these; the others clip or wrap their state.
    unclipped = {name for name, scene in ll.SCENES.items() if not scene.projects_state()}
    assert unclipped >= {"CartPole", "CartPoleContinuous", "VanDerPol", "DoubleCartPole"}
