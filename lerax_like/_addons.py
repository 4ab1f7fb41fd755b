"""Scene add-ons given flat: generalised forces and contacts built from their keywords."""

import dataclasses

from .physics.contact import AbstractContact
from .physics.friction import AbstractCoulombFriction


def _field_of(addon: type) -> str:
    """The scene field that holds an add-on of class `addon`."""
    if issubclass(addon, AbstractContact):
        return "contacts"
    if issubclass(addon, AbstractCoulombFriction):
        return "friction"
    return "forces"


def gather_addons(cls, keywords) -> None:
    """Build the add-ons whose parameters are given flat (`joint_damping=0.5`) into `forces`, `contacts`, `friction`.

    An add-on is selected by a keyword only it takes (`end_stop_stiffness` selects the penalty
    `EndStops`, `restitution` the located `Walls`); a keyword several take (`track_limit`) goes
    to the selected one, or to the first that takes it when none is selected. Two selected
    add-ons that share a keyword are two models of one thing, and are refused.
    """
    addons = {field: list(keywords.pop(field, ())) for field in ("forces", "contacts", "friction")}
    names = {addon: {f.name for f in dataclasses.fields(addon)} for addon in cls.addons}
    shared = {name for addon in cls.addons for name in names[addon] if sum(name in n for n in names.values()) > 1}
    selected = [addon for addon in cls.addons if (names[addon] - shared) & set(keywords)]
    if not selected:
        selected = [addon for addon in cls.addons if names[addon] & set(keywords)][:1]
    for i, first in enumerate(selected):
        for second in selected[i + 1 :]:
            if names[first] & names[second]:
                raise ValueError(
                    f"{cls.__name__}: give the keywords of either {first.__name__} "
                    f"({', '.join(sorted(names[first] - shared))}) or {second.__name__} "
                    f"({', '.join(sorted(names[second] - shared))}), not both: they model the same contact"
                )
    for addon in selected:
        given = {name: keywords[name] for name in names[addon] if name in keywords}
        built = addon(**given)
        # An add-on that acts as if absent (friction coefficients given as zero) is not built
        # in, so that the scene computes none of it (CartPole stays Gymnasium's bit for bit).
        if not getattr(built, "absent", False):
            addons[_field_of(addon)].append(built)
    for addon in selected:
        for name in names[addon]:
            keywords.pop(name, None)
    for field, values in addons.items():
        if values:
            keywords[field] = tuple(values)


__all__ = ["gather_addons"]
