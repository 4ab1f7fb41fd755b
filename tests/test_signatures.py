"""Constructors are Equinox's own: the signature is the dataclass's, and says what the call takes;
flat keywords are resolved in one place, `lerax_like.make`, which names the closest valid keyword
to a misspelt one.

Every registered scene (`ll.SCENES`, the test scenes included) and every concrete dynamics, add-on
and contact of the package is covered, so a scene or a field added later is checked with no line
changed here. The expected keywords and defaults are read from `dataclasses.fields`, not listed.
"""

import dataclasses
import inspect
import pkgutil
import importlib

import equinox as eqx
import gymnasium
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like._fields import AbstractParametrised, parameter_range
from lerax_like.scenes._make import flat_keywords


def _package_classes() -> list[type]:
    """Every concrete class of the package that is an Equinox module."""
    found = {}
    for module in pkgutil.walk_packages(ll.__path__, "lerax_like."):
        if module.name.startswith(("lerax_like.sb3", "lerax_like.gymnax")) or module.name.endswith("__main__"):
            continue
        for value in vars(importlib.import_module(module.name)).values():
            if isinstance(value, type) and value.__module__.startswith("lerax_like") and issubclass(value, eqx.Module):
                found[f"{value.__module__}.{value.__qualname__}"] = value
    return [cls for _, cls in sorted(found.items())]


CLASSES = _package_classes()
PARAMETRISED = [
    cls for cls in CLASSES
    if issubclass(cls, AbstractParametrised) and not inspect.isabstract(cls) and not cls.__name__.startswith("Abstract")
]
SCENES = sorted(ll.SCENES.items())


def test_no_class_of_the_package_defines_a_signature_and_every_init_is_a_plain_function():
    for cls in CLASSES:
        for klass in cls.__mro__:
            assert "__signature__" not in vars(klass), klass
        assert inspect.isfunction(cls.__init__), cls


@pytest.mark.parametrize("cls", PARAMETRISED, ids=lambda cls: cls.__name__)
def test_a_signature_is_the_dataclass_fields_with_their_defaults(cls):
    parameters = inspect.signature(cls).parameters
    fields = [field for field in dataclasses.fields(cls) if field.init]
    assert sorted(parameters) == sorted(field.name for field in fields)
    for field in fields:
        shown = parameters[field.name].default
        if field.default is not dataclasses.MISSING:
            assert shown == field.default, field.name
        elif field.default_factory is dataclasses.MISSING:
            assert shown is inspect.Parameter.empty, field.name


@pytest.mark.parametrize("cls", PARAMETRISED, ids=lambda cls: cls.__name__)
def test_a_positional_call_is_accepted_exactly_when_the_signature_binds_it(cls):
    signature = inspect.signature(cls)
    positional = [
        p for p in signature.parameters.values() if p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    ]
    required = {p.name: _a_value(cls, p.name) for p in signature.parameters.values() if p.default is p.empty}
    keyword_only = {name: value for name, value in required.items() if signature.parameters[name].kind is inspect.Parameter.KEYWORD_ONLY}
    # Every positional parameter given by position, in order: the signature binds it, so the call works.
    values = [required[p.name] if p.name in required else _default_of(cls, p.name) for p in positional]
    signature.bind(*values, **keyword_only)
    assert eqx.tree_equal(cls(*values, **keyword_only), cls(**{p.name: v for p, v in zip(positional, values)}, **keyword_only))
    # One more positional value than the signature has places for: refused by both.
    with pytest.raises(TypeError):
        signature.bind(*values, None, **keyword_only)
    with pytest.raises(TypeError):
        cls(*values, None, **keyword_only)
    for name, value in keyword_only.items():  # a keyword-only parameter given by position: refused by both
        others = {k: v for k, v in keyword_only.items() if k != name}
        with pytest.raises(TypeError):
            signature.bind(*values, value, **others)
        with pytest.raises(TypeError):
            cls(*values, value, **others)


def _default_of(cls, name):
    field = {f.name: f for f in dataclasses.fields(cls)}[name]
    return field.default if field.default is not dataclasses.MISSING else field.default_factory()


def _a_value(cls, name):
    """A valid value for a required field: a coefficient (0.5 lies in every range they have) or
    the dynamics that `ForcedDynamics` adds forces to."""
    if name == "dynamics":
        return ll.CartPoleDynamics()
    assert parameter_range({f.name: f for f in dataclasses.fields(cls)}[name]) is not None, (cls, name)
    return 0.5


@pytest.mark.parametrize(("name", "scene"), SCENES, ids=[name for name, _ in SCENES])
def test_make_takes_the_fields_the_dynamics_parameters_the_integrator_settings_and_the_addons(name, scene):
    taken = flat_keywords(scene)
    fields = {field.name for field in dataclasses.fields(scene) if field.init}
    assert taken["scene"] == fields | {alias for alias, _ in scene.aliases}
    built = scene()
    assert taken["dynamics"] == {f.name for f in dataclasses.fields(built.dynamics) if f.init} - fields
    assert taken["integrator"] == set(inspect.signature(ll.make_integrator).parameters)
    for addon in scene.addons:
        assert taken[addon.__name__] == {f.name for f in dataclasses.fields(addon)} - fields
    # The defaults of the flat keywords are those of the default build.
    flat = {
        keyword: getattr(built.dynamics, keyword) for keyword in taken["dynamics"]
    }
    assert bool(eqx.tree_equal(ll.make(scene, **flat), built))


@pytest.mark.parametrize(
    ("build", "keyword", "nearest"),
    [
        (lambda: ll.make("CartPole", pole_mas=0.2), "pole_mas", "pole_mass"),  # the dynamics'
        (lambda: ll.make("CartPole", restitutoin=0.5), "restitutoin", "restitution"),  # an add-on's
        (lambda: ll.make("CartPole", stepsize_controler=None), "stepsize_controler", "stepsize_controller"),  # the integrator's
        (lambda: ll.make("Pendulum", max_sped=8.0), "max_sped", "max_speed"),  # the task's
        (lambda: gymnasium.make("lerax_like/CartPole-v1", gravty=9.8), "gravty", "gravity"),  # Gymnasium's
    ],
)
def test_a_misspelt_flat_keyword_names_the_closest_valid_one(build, keyword, nearest):
    with pytest.raises(TypeError, match=rf"unknown keyword\(s\) {keyword} \(did you mean {nearest}\?\)"):
        build()


def test_a_misspelt_field_is_refused_by_the_dataclass():
    with pytest.raises(TypeError, match="gravty"):
        ll.CartPoleDynamics(gravty=9.8)  # pyright: ignore[reportCallIssue]
    with pytest.raises(TypeError, match="joint_dampng"):
        ll.physics.JointDamping(joint_dampng=0.1)  # pyright: ignore[reportCallIssue]


def test_make_and_gymnasium_keywords_reach_the_dynamics_and_a_class_is_taken_as_well_as_a_name():
    env = gymnasium.make("lerax_like/CartPole-v1", gravity=3.7)
    assert float(env.unwrapped.scene.dynamics.gravity) == 3.7
    assert float(ll.make("Pendulum", g=3.7).dynamics.gravity) == 3.7
    assert float(ll.make(ll.CartPole, pole_mass=jnp.asarray(0.2)).dynamics.pole_mass) == 0.2
    np.testing.assert_array_equal(
        np.asarray(ll.make("CartPole", pole_mass=0.2).dynamics.pole_mass),
        np.asarray(ll.CartPole(dynamics=ll.CartPoleDynamics(pole_mass=0.2)).dynamics.pole_mass),
    )
    with pytest.raises(ValueError, match="did you mean CartPole"):
        ll.make("CartPol")


def test_the_integrator_field_converts_a_preset_name_or_a_solver():
    assert isinstance(ll.CartPole(integrator="rk4").integrator.solver, ll.RK4)
    assert bool(eqx.tree_equal(ll.CartPole(integrator="tsit5"), ll.make("CartPole", solver="tsit5")))
    with pytest.raises(TypeError, match="either integrator= or solver settings"):
        ll.make("CartPole", integrator="rk4", solver="euler")
