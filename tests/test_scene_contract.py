"""The scene contract, checked for every scene in `lerax_like.SCENES`.

A scene is covered here the moment it is registered, the package's own and those that test
modules register (`tests/conftest.py` imports them before collection): its Gymnasium-style
docstring, its declared `stochastic` against its behaviour, construction errors that name
the parameter, and energy conservation wherever its
dynamics claim it (checked against a Dopri8 solve at rtol 1e-12, not against the scene's
own solver). Nothing here counts scenes: everything is read off `lerax_like.SCENES`.
`jit`, `vmap`, `grad` and `jacfwd` composed through a rollout of every scene, its reward
included, are checked against central differences in tests/test_batched_gradients.py, which
also reads `lerax_like.SCENES`.
"""

import dataclasses
import importlib
import operator
import pkgutil
import typing

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
import pytest
from conftest import quick_unless_hybrid

import lerax_like as ll
from lerax_like._fields import parameter_range


SECTIONS = ("Description", "Action Space", "Observation Space", "Rewards", "Starting State", "Episode End", "Arguments")
NAMES = sorted(ll.SCENES)


def _package_scenes():
    """Every concrete `AbstractEnv` subclass defined in a module under `lerax_like/scenes/`."""
    found = []
    for module in pkgutil.iter_modules(ll.scenes.__path__, f"{ll.scenes.__name__}."):
        for value in vars(importlib.import_module(module.name)).values():
            if (
                isinstance(value, type)
                and issubclass(value, ll.AbstractEnv)
                and value.__module__ == module.name
                and not ll.scenes.is_abstract_scene(value)
            ):
                found.append(value)
    return found


def test_every_scene_under_scenes_is_registered():
    # A forgotten `@register_scene` (or import in `scenes/__init__.py`) would otherwise leave a
    # scene out of every test, study and Gymnasium id, silently.
    scenes = _package_scenes()
    assert scenes, "no scene found under lerax_like/scenes/"
    missing = [scene.__name__ for scene in scenes if ll.SCENES.get(scene.__name__) is not scene]
    assert not missing, f"decorate with @register_scene and import in lerax_like/scenes/__init__.py: {missing}"
    # And the search finds every scene the package registers: it would see a forgotten one.
    registered = {scene for scene in ll.SCENES.values() if scene.__module__.startswith(ll.scenes.__name__)}
    assert registered == set(scenes)


def test_the_registry_names_each_scene_by_its_class():
    for name, scene in ll.SCENES.items():
        assert scene.__name__ == name
        if scene.__module__.startswith("lerax_like."):
            assert getattr(ll, name) is scene  # the package's scenes, re-exported from the one registry


def test_register_scene_refuses_what_is_not_a_concrete_final_scene():
    with pytest.raises(TypeError, match="subclass of lerax_like.AbstractEnv"):
        ll.register_scene(ll.CartPoleDynamics)
    with pytest.raises(TypeError, match="AbstractCartPole is abstract: it does not declare action_space"):
        ll.register_scene(ll.scenes.AbstractCartPole)

    @typing.final
    class Unscaled(ll.AbstractUnitActionEnv):  # a unit action that says neither how it acts nor its scale
        stochastic: typing.ClassVar[bool] = False
        action_size: typing.ClassVar[int] = 1
        dynamics: ll.VanDerPolDynamics = eqx.field(default_factory=ll.VanDerPolDynamics)
        integrator: ll.Integrator = eqx.field(default="rk4", converter=ll.make_integrator)
        dt: jax.Array = eqx.field(default=0.05, converter=ll.POSITIVE)
        max_episode_steps: int | None = ll.env.episode_limit(10)
        initial_bounds = worst_reward = None

        def reward(self, state, action, next_state, *, key):
            return 0.0

    with pytest.raises(TypeError, match=r"Unscaled is abstract: it does not declare action_scale \(or physical_input\)"):
        ll.register_scene(Unscaled)

    class Unmarked(ll.CartPole):  # concrete, but not @final
        pass

    with pytest.raises(TypeError, match="Unmarked must be marked @typing.final"):
        ll.register_scene(Unmarked)

    @typing.final
    class CartPole(ll.CartPole):  # a second class under a registered name
        pass

    with pytest.raises(ValueError, match="a scene named CartPole is already registered"):
        ll.register_scene(CartPole)
    assert ll.SCENES["CartPole"] is ll.CartPole
    assert ll.register_scene(ll.CartPole) is ll.CartPole  # again: nothing changes


@pytest.mark.parametrize("name", NAMES)
def test_docstring_has_gymnasium_sections(name):
    doc = ll.SCENES[name].__doc__ or ""
    missing = [section for section in SECTIONS if f"## {section}" not in doc]
    assert not missing, f"{name}'s docstring lacks the sections {missing}"


@pytest.mark.parametrize("name", NAMES)
def test_metadata_is_declared(name):
    scene = ll.SCENES[name]
    assert isinstance(scene.stochastic, bool) and isinstance(scene.stiff, bool)
    assert getattr(scene, "__final__", False), f"{name} is concrete: mark it @final"
    env = scene()
    declared = {spec.scene: spec.declared for spec in ll.gym.SPECS.values()}.get(scene)  # the Gymnasium layer's
    if declared is not None:
        assert isinstance(declared, ll.gym.GymnasiumSpec)
        for _, path in declared.attributes:
            operator.attrgetter(path)(env)  # every mapped attribute exists


def _sample_action(env, key):
    return env.action_space.sample(key=key)


@pytest.mark.parametrize("name", [quick_unless_hybrid(name) for name in NAMES])
def test_declared_stochastic_matches_behaviour(name):
    env = ll.SCENES[name]()
    state, _, _ = env.reset(key=jr.key(0))
    action = _sample_action(env, jr.key(1))
    # One compiled step for both keys: run eagerly, every operation around the solve compiled
    # on its own (minutes for a scene with events on a loaded machine).
    advance = eqx.filter_jit(lambda state, action, key: env.advance(state, action, key=key))
    first = advance(state, action, jr.key(2))
    second = advance(state, action, jr.key(3))
    same = all(np.array_equal(a, b) for a, b in zip(jax.tree.leaves(first), jax.tree.leaves(second)))
    if not env.stochastic:
        assert same, f"{name} declares stochastic=False but its step depends on the key"


def _parameter_fields(module):
    return [field for field in dataclasses.fields(module) if parameter_range(field) is not None]


@pytest.mark.parametrize("name", NAMES)
def test_construction_errors_name_the_parameter(name):
    scene = ll.SCENES[name]
    env = scene()
    # The task's own parameters and, flat, the dynamics' parameters.
    names = [field.name for field in _parameter_fields(scene)]
    names += [field.name for field in _parameter_fields(env.dynamics)]
    assert names, f"{name} declares no checked parameter"
    for parameter in names:
        with pytest.raises(ValueError, match=parameter):
            ll.make(scene, **{parameter: np.nan})
        with pytest.raises(TypeError, match=parameter):
            ll.make(scene, **{parameter: "heavy"})
    with pytest.raises(TypeError, match="no_such_parameter"):
        ll.make(scene, no_such_parameter=1.0)


@pytest.mark.parametrize("name", NAMES)
def test_dynamics_may_be_given_as_a_module(name):
    scene = ll.SCENES[name]
    dynamics = scene().dynamics
    env = scene(dynamics=dynamics)
    assert env.dynamics is dynamics
    first = next(field.name for field in dataclasses.fields(dynamics) if eqx.is_array(getattr(dynamics, field.name)))
    with pytest.raises(TypeError, match="not both"):
        ll.make(scene, dynamics=dynamics, **{first: getattr(dynamics, first)})


class _Clock(eqx.Module):
    """A scene's dynamics, recording the time `t` at which each call reads its vector field."""

    dynamics: ll.AbstractDynamics

    def vector_field(self, t, y, u):
        jax.debug.callback(_TIMES.append, t)
        return self.dynamics.vector_field(t, y, u)

    def forced_vector_field(self, t, y, u, generalised_force):
        # The field under a generalised force, which located friction calls in place of
        # `vector_field` (lerax_like.stick_slip).
        jax.debug.callback(_TIMES.append, t)
        return self.dynamics.forced_vector_field(t, y, u, generalised_force)

    def __getattr__(self, name):
        # Everything else (velocity_indices, coordinates, a contact's reads) is the dynamics'.
        if name == "dynamics" or name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.dynamics, name)


_TIMES = []


@eqx.filter_jit
def _step(env, state, action, key):
    return env.step(state, action, key=key)


@pytest.mark.parametrize("name", [quick_unless_hybrid(name) for name in NAMES])
def test_the_vector_field_reads_the_episode_time(name):
    # A driven force (`cos(w t)`) is right only if `t` runs on over the episode: step k reads
    # the field within [k dt, (k + 1) dt], from k dt. A step whose clock restarts at 0 (or a
    # scene whose own `evolve` forgets `t0`) reads [0, dt] and fails here.
    env = ll.SCENES[name]()
    clocked = eqx.tree_at(lambda e: e.dynamics, env, _Clock(env.dynamics))
    state, _, _ = clocked.reset(key=jr.key(0))
    assert float(ll.env.episode_time(state.steps, env.dt)) == 0.0
    k = 7
    state = ll.EnvState(y=state.y, steps=state.steps + k)
    action = _sample_action(env, jr.key(1))
    _TIMES.clear()
    next_state, _, _, _, _, info = _step(clocked, state, action, jr.key(2))
    jax.effects_barrier()
    assert bool(info["solver_ok"]) and _TIMES
    times, dt = np.asarray(_TIMES, dtype=np.float64), float(env.dt)
    slack = 4 * np.spacing((k + 1) * dt)
    assert times.min() == pytest.approx(k * dt, abs=slack), f"{name}: the step's first read is at t={times.min()}"
    assert times.max() <= (k + 1) * dt + slack, f"{name}: the step read the field at t={times.max()}"
    # The time limit's autoreset starts the next episode at time 0.
    if env.max_episode_steps is not None:
        last = ll.EnvState(y=state.y, steps=state.steps - k + env.max_episode_steps - 1)
        fresh, _, _, _, truncated, _ = _step(clocked, last, action, jr.key(3))
        assert bool(truncated) and float(ll.env.episode_time(fresh.steps, env.dt)) == 0.0


def _tight(env):
    controller = diffrax.PIDController(rtol=1e-12, atol=1e-12)
    return eqx.tree_at(lambda e: e.integrator, env, ll.make_integrator("dopri8", controller, max_steps=100_000))


@pytest.mark.parametrize("name", [quick_unless_hybrid(name) for name in NAMES])
def test_energy_is_conserved_with_zero_input_where_claimed(name):
    with jax.enable_x64(True):
        env = ll.SCENES[name]()
        physics = env.physics
        if not (isinstance(physics, ll.AbstractConservativeDynamics) and physics.conserves_energy):
            pytest.skip(f"{name}'s dynamics claim no conserved energy")
        if getattr(env, "contacts", ()):
            # Impacts dissipate unless elastic: checked with restitution 1 (tests/test_contact.py
            # checks the energy lost at each impact).
            env = eqx.tree_at(lambda e: [c.restitution for c in e.contacts], env, replace_fn=jnp.ones_like)
        if getattr(env, "friction", ()):
            # Dry friction dissipates: checked with its coefficients zero (tests/test_friction_block.py
            # checks a stop against its closed form).
            env = eqx.tree_at(lambda e: e.friction, env, replace_fn=lambda f: jax.tree.map(jnp.zeros_like, f))
        if getattr(env, "floor", None) is not None:
            # A disk's floor (RollingDisk) dissipates by friction and restitution: checked frictionless
            # and elastic (tests/test_rolling_disk.py checks its impacts and its skid against closed forms).
            env = eqx.tree_at(
                lambda e: (e.floor.static_friction, e.floor.kinetic_friction, e.floor.restitution),
                env, replace_fn=lambda p: jnp.zeros_like(p),
            )
            env = eqx.tree_at(lambda e: e.floor.restitution, env, replace_fn=jnp.ones_like)
        env = _tight(env)
        state, _, _ = env.reset(key=jr.key(0))
        zero = jnp.zeros_like(env.physical_input(_sample_action(env, jr.key(1))))

        def body(state, _):
            state, info = env.evolve(state, zero)
            return state, (physics.energy(state.y), info["solver_ok"])

        _, (energies, ok) = jax.lax.scan(body, state, None, length=50)
        assert np.all(np.asarray(ok))
        start = float(physics.energy(state.y))
        scale = max(1.0, abs(start), float(jnp.max(jnp.abs(energies))))
        drift = float(jnp.max(jnp.abs(energies - start)))
        assert drift < 1e-9 * scale, f"{name}: energy drifts by {drift:.2e} over 50 steps"


@pytest.mark.slow  # 5.3 s of one worker at 4f7dc26 (docs/testing.md): CI's, not the quick loop's
def test_acrobot_nips_claims_no_energy_and_indeed_conserves_none():
    # The NeurIPS equations drop a Coriolis term: the book energy is not conserved.
    with jax.enable_x64(True):
        env = ll.make("Acrobot", equations="nips")
        assert not env.physics.conserves_energy
        env = _tight(eqx.tree_at(lambda e: e.max_velocity_1, env, jnp.inf))
        state = ll.EnvState(y=jnp.array([1.0, 0.5, 0.0, 0.0]), steps=jnp.asarray(0))
        energy = env.physics.energy
        end = state
        for _ in range(20):
            end, _ = env.evolve(end, jnp.zeros(1))
        assert abs(float(energy(end.y) - energy(state.y))) > 1e-3
