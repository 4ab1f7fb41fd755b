"""A scene from flat keywords, as Gymnasium, gymnax and the command line pass them: `make`.

A scene's own constructor takes its fields (`CartPole(dynamics=CartPoleDynamics(pole_mass=0.2),
integrator="rk4")`). Users of Gymnasium and gymnax pass everything flat instead
(`gymnasium.make("lerax_like/CartPole-v1", pole_mass=0.2, solver="rk4")`): this module routes
each flat keyword to the part that takes it, in one place that every layer calls.
"""

import dataclasses
import difflib
from typing import Any

from .._fields import AbstractParametrised
from ..env import AbstractEnv
from ..integrate import make_integrator
from ..physics.contact import AbstractContact
from ..physics.friction import AbstractCoulombFriction
from ._registry import SCENES

INTEGRATOR_KEYWORDS = ("solver", "stepsize_controller", "max_steps", "adjoint", "substeps")
ADDON_FIELDS = ("forces", "contacts", "friction")


def _names(cls: type) -> set[str]:
    return {field.name for field in dataclasses.fields(cls) if field.init}


def _parts(scene: type[AbstractEnv]) -> dict[str, Any]:
    """The fields of `scene` that hold one parametrised part by default (its `dynamics`, a disk's
    `floor`), with the factory that builds it."""
    return {
        field.name: field.default_factory
        for field in dataclasses.fields(scene)
        if field.init and field.default_factory is not dataclasses.MISSING
        and isinstance(field.default_factory(), AbstractParametrised)
    }


def flat_keywords(scene: type[AbstractEnv]) -> dict[str, set[str]]:
    """What `make` takes for `scene`, by where it goes: `"scene"` (its fields and aliases), each
    part by its field's name (`"dynamics"`: its dynamics' parameters), `"integrator"` (the
    settings of `make_integrator`) and one entry per add-on class (its parameters)."""
    fields = {field.name for field in dataclasses.fields(scene) if field.init}
    taken = {"scene": fields | {alias for alias, _ in scene.aliases}}
    for name, factory in _parts(scene).items():
        taken[name] = _names(type(factory())) - taken["scene"]
    if "integrator" in fields:
        taken["integrator"] = set(INTEGRATOR_KEYWORDS)
    for addon in scene.addons:
        taken[addon.__name__] = _names(addon) - taken["scene"]
    return taken


def refuse_unknown(owner: str, given, known) -> None:
    """Refuse keywords not in `known`, naming for each the closest one that is."""
    known = sorted(known)
    unknown = sorted(set(given) - set(known))
    if not unknown:
        return
    hints = []
    for name in unknown:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hints.append(f"{name} (did you mean {close[0]}?)" if close else name)
    raise TypeError(f"{owner} got unknown keyword(s) {', '.join(hints)}; it takes {', '.join(known)}")


def make(scene: str | type[AbstractEnv], /, **keywords: Any) -> AbstractEnv:
    """The scene `scene` (a name of `SCENES`, or a scene class) built from flat keywords.

    Besides the scene's own fields, it takes its dynamics' parameters (`pole_mass=0.2`), the
    integrator's settings (`solver`, `stepsize_controller`, `max_steps`, `adjoint`, `substeps`:
    `make_integrator`), its add-ons' parameters (`joint_damping=0.5`, `restitution=0.8`) and its
    aliases (Gymnasium's names, such as Pendulum's `g`). A keyword that none of them takes is
    refused naming the closest one that is.

    An add-on is selected by a keyword only it takes (`end_stop_stiffness` selects the penalty
    `EndStops`, `restitution` the located `Walls`); a keyword several take (`track_limit`) goes
    to the selected one, or to the first that takes it when none is selected. Two selected
    add-ons that share a keyword are two models of one thing, and are refused.
    """
    cls = SCENES[scene] if isinstance(scene, str) and scene in SCENES else scene
    if not (isinstance(cls, type) and issubclass(cls, AbstractEnv)):
        close = difflib.get_close_matches(str(scene), list(SCENES), n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ValueError(f"unknown scene {scene!r}{hint}; known scenes: {', '.join(SCENES)}")
    taken = flat_keywords(cls)
    refuse_unknown(cls.__name__, keywords, set().union(*taken.values()))
    for alias, name in cls.aliases:
        if alias in keywords:
            keywords[name] = keywords.pop(alias)
    fields = {field.name: field for field in dataclasses.fields(cls)}
    for part, factory in _parts(cls).items():  # the part's class, or a partial of it
        flat = {name: keywords.pop(name) for name in list(keywords) if name in taken[part]}
        if flat:
            if part in keywords:
                raise TypeError(f"{cls.__name__}: give either {part}= or its parameters ({', '.join(sorted(flat))}), not both")
            keywords[part] = factory(**flat)
    settings = {name: keywords.pop(name) for name in INTEGRATOR_KEYWORDS if name in keywords}
    if settings:
        if "integrator" in keywords:
            raise TypeError(f"give either integrator= or solver settings ({', '.join(settings)}), not both")
        settings.setdefault("solver", fields["integrator"].default)
        keywords["integrator"] = make_integrator(settings.pop("solver"), **settings)
    _gather_addons(cls, taken, keywords)
    return cls(**keywords)


def _gather_addons(cls: type[AbstractEnv], taken: dict[str, set[str]], keywords: dict[str, Any]) -> None:
    """Build the add-ons whose parameters are given flat into the fields `forces`, `contacts`, `friction`."""
    addons = {field: list(keywords.pop(field, ())) for field in ADDON_FIELDS}
    names = {addon: taken[addon.__name__] for addon in cls.addons}
    shared = {name for addon in cls.addons for name in names[addon] if sum(name in n for n in names.values()) > 1}
    selected = [addon for addon in cls.addons if (names[addon] - shared) & set(keywords)]
    if not selected:
        selected = [addon for addon in cls.addons if names[addon] & set(keywords)][:1]
    for i, first in enumerate(selected):
        for second in selected[i + 1 :]:
            # `max_events` (a step's budget of located events) is every located add-on's own.
            if (names[first] & names[second]) - {"max_events"}:
                raise ValueError(
                    f"{cls.__name__}: give the keywords of either {first.__name__} "
                    f"({', '.join(sorted(names[first] - shared))}) or {second.__name__} "
                    f"({', '.join(sorted(names[second] - shared))}), not both: they model the same contact"
                )
    for addon in selected:
        built = addon(**{name: keywords[name] for name in names[addon] if name in keywords})
        # An add-on that acts as if absent (friction coefficients given as zero) is not built
        # in, so that the scene computes none of it (CartPole stays Gymnasium's bit for bit).
        if not getattr(built, "absent", False):
            addons[_field_of(addon)].append(built)
    for addon in selected:
        for name in names[addon]:
            keywords.pop(name, None)
    keywords.update({field: tuple(values) for field, values in addons.items() if values})


def _field_of(addon: type) -> str:
    """The scene field that holds an add-on of class `addon`."""
    if issubclass(addon, AbstractContact):
        return "contacts"
    if issubclass(addon, AbstractCoulombFriction):
        return "friction"
    return "forces"
