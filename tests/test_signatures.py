"""Constructors say what they take: signatures read from the fields, typed blocks that are current,
and a misspelt keyword answered with the closest valid one.

Every registered scene (`ll.SCENES`, the test scenes included) and every final dynamics, add-on
and contact of the package is covered, so a scene or a field added later is checked with no line
changed here. The expected keywords and defaults are read from `dataclasses.fields` of the class,
of its dynamics and of its add-ons, and from `make_integrator`'s own signature, not listed here.
"""

import dataclasses
import inspect
import re

import equinox as eqx
import gymnasium
import jax.numpy as jnp
import numpy as np
import pytest

import lerax_like as ll
from lerax_like._constructor_source import (
    constructor_source,
    current,
    final_classes,
    groups,
    keywords_module_current,
)
from lerax_like._fields import AbstractParametrised


SCENES = sorted(ll.SCENES.items())
PARAMETRISED = sorted(
    {cls for cls in final_classes() if issubclass(cls, AbstractParametrised)}
    | {scene.__dataclass_fields__["dynamics"].default_factory().__class__ for _, scene in SCENES},
    key=lambda cls: cls.__name__,
)


def plain_default(field: dataclasses.Field):
    """A field's default as declared, or `MISSING` when it is built per instance."""
    if field.metadata.get("default_from") is not None:
        return dataclasses.MISSING
    return field.default


@pytest.mark.parametrize("cls", PARAMETRISED, ids=lambda cls: cls.__name__)
def test_a_dynamics_signature_lists_its_fields_with_their_defaults(cls):
    parameters = inspect.signature(cls).parameters
    fields = [field for field in dataclasses.fields(cls) if field.init]
    assert list(parameters) == [field.name for field in fields]
    for field in fields:
        default = plain_default(field)
        if default is dataclasses.MISSING:
            assert parameters[field.name].default is inspect.Parameter.empty
        else:
            assert parameters[field.name].default == default, field.name


@pytest.mark.parametrize(("name", "scene"), SCENES, ids=[name for name, _ in SCENES])
def test_a_scenes_signature_lists_fields_dynamics_integrator_and_addons_with_defaults(name, scene):
    parameters = inspect.signature(scene).parameters
    fields = {field.name: field for field in dataclasses.fields(scene) if field.init}
    for field in fields.values():
        assert field.name in parameters
        if plain_default(field) is not dataclasses.MISSING:
            assert parameters[field.name].default == field.default, field.name
    # The flat keywords: the defaults of the dynamics that the scene builds by default.
    built = scene()
    for field in dataclasses.fields(built.dynamics):
        if field.name in fields:
            continue
        assert field.name in parameters, f"{name} does not show its dynamics' {field.name}"
        shown, value = parameters[field.name].default, getattr(built.dynamics, field.name)
        if field.metadata.get("parameter"):
            np.testing.assert_array_equal(np.asarray(shown, float), np.asarray(value), err_msg=field.name)
        else:
            assert shown == value, field.name
    for keyword, default in inspect.signature(ll.make_integrator).parameters.items():
        assert keyword in parameters
        if keyword != "solver":
            assert parameters[keyword].default == default.default
    for addon in scene.addons:
        for field in dataclasses.fields(addon):
            assert parameters[field.name].default is None, "an add-on is absent unless its keywords are given"
    for alias, _ in scene.aliases:
        assert alias in parameters
    # Nothing else: every keyword shown is taken.
    takes = set(fields) | {f.name for f in dataclasses.fields(built.dynamics)}
    takes |= set(inspect.signature(ll.make_integrator).parameters) | {alias for alias, _ in scene.aliases}
    takes |= {field.name for addon in scene.addons for field in dataclasses.fields(addon)}
    assert set(parameters) == takes


@pytest.mark.parametrize(("name", "scene"), SCENES, ids=[name for name, _ in SCENES])
def test_a_scene_built_from_its_shown_defaults_is_its_default(name, scene):
    """The defaults shown are the ones used: passing them all (flat) builds the default scene."""
    shown = {
        keyword: parameter.default
        for keyword, parameter in inspect.signature(scene).parameters.items()
        if isinstance(parameter.default, (bool, int, float, str, tuple))
        and keyword not in {alias for alias, _ in scene.aliases}
        and keyword not in {"forces", "contacts"}
    }
    assert bool(eqx.tree_equal(scene(**shown), scene()))


def test_the_cartpole_signature_prints_its_keywords():
    text = str(inspect.signature(ll.CartPole))
    for keyword in ("pole_mass: 'ScalarLike' = 0.1", "dt: 'ScalarLike' = 0.02", "solver:", "joint_damping:", "restitution:"):
        assert keyword in text
    assert "pole_mass" in (ll.CartPole.__init__.__doc__ or "") or "pole_mass" in str(inspect.signature(ll.CartPole.__init__))


@pytest.mark.parametrize("cls", final_classes(), ids=lambda cls: cls.__name__)
def test_every_final_class_declares_its_constructor_to_a_type_checker(cls):
    assert current(cls), (
        f"{cls.__module__}.{cls.__name__}'s constructor block is not current: run "
        f"`python -m lerax_like._constructor_source --write`, or paste after its docstring:\n\n{constructor_source(cls)}"
    )


def test_the_shared_keywords_module_is_current_and_each_group_is_declared_once():
    assert keywords_module_current(), (
        "lerax_like/_keywords.py is not current: run `python -m lerax_like._constructor_source --write`"
    )
    import lerax_like._keywords as shared

    for group in groups():
        declared = getattr(shared, group.name).__annotations__
        assert list(declared) == [key for key, _ in group.keywords], group.name
    # Each group's keywords stand in the module once, and in no block: a block lists only its own.
    for cls in final_classes():
        block = constructor_source(cls)
        listed = set(re.findall(r"^ {12}(\w+):", block, re.MULTILINE))
        for group in groups():
            if re.search(rf"\b{group.name}\b", block):
                assert not listed & {key for key, _ in group.keywords}, (cls.__name__, group.name)


@pytest.mark.parametrize(("name", "scene"), SCENES, ids=[name for name, _ in SCENES])
def test_a_scenes_block_takes_exactly_the_keywords_of_its_signature(name, scene):
    """What a block declares (its own keywords and its groups') is what the runtime signature takes."""
    if not scene.__module__.startswith("lerax_like."):
        pytest.skip("a test scene declares no block")
    block = constructor_source(scene)
    taken = set(re.findall(r"^ {12}(\w+):", block, re.MULTILINE))
    taken |= {key for group in groups() if re.search(rf"\b{group.name}\b", block) for key, _ in group.keywords}
    assert taken == set(inspect.signature(scene).parameters), name


@pytest.mark.parametrize(
    ("build", "keyword", "nearest"),
    [
        (lambda: ll.CartPole(pole_mas=0.2), "pole_mas", "pole_mass"),  # the dynamics'
        (lambda: ll.CartPole(restitutoin=0.5), "restitutoin", "restitution"),  # an add-on's
        (lambda: ll.CartPole(stepsize_controler=None), "stepsize_controler", "stepsize_controller"),  # the integrator's
        (lambda: ll.Pendulum(max_sped=8.0), "max_sped", "max_speed"),  # the task's
        (lambda: ll.CartPoleDynamics(gravty=9.8), "gravty", "gravity"),
        (lambda: ll.physics.JointDamping(joint_dampng=0.1), "joint_dampng", "joint_damping"),
    ],
)
def test_a_misspelt_keyword_names_the_closest_valid_one(build, keyword, nearest):
    with pytest.raises(TypeError, match=rf"unknown keyword\(s\) {keyword} \(did you mean {nearest}\?\)"):
        build()


def test_gymnasium_keywords_still_reach_the_dynamics():
    env = gymnasium.make("lerax_like/CartPole-v1", gravity=3.7)
    assert float(env.unwrapped.scene.dynamics.gravity) == 3.7
    assert float(ll.Pendulum(g=3.7).dynamics.gravity) == 3.7
    assert float(ll.CartPole(pole_mass=jnp.asarray(0.2)).dynamics.pole_mass) == 0.2
