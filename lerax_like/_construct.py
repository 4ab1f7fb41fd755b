"""A scene built from keywords: its fields, and the flat keywords of its dynamics
(`pole_mass=0.2`), its integrator (`solver="rk4"`) and its add-ons (`joint_damping=0.5`),
each routed to the part that takes it; a keyword none takes is refused naming the closest
(the keywords are those of the scene's signature, `lerax_like._signatures`)."""

import dataclasses
import inspect

from ._addons import gather_addons
from ._fields import assign_fields
from ._signatures import Keyword, annotation_text, refuse_unknown
from .integrate import make_integrator


INTEGRATOR_KEYWORDS = ("solver", "stepsize_controller", "max_steps", "adjoint", "substeps")


def integrator_keywords() -> list[Keyword]:
    """The integrator's flat keywords, as `make_integrator` declares them."""
    declared = inspect.signature(make_integrator).parameters
    return [Keyword(name, declared[name].default, annotation_text(make_integrator, name)) for name in INTEGRATOR_KEYWORDS]


def construct_scene(self, *fields, **keywords):
    """Every field by keyword (or by position, in declaration order); besides, the
    dynamics' parameters and the integrator's settings (`solver`, `stepsize_controller`,
    `max_steps`, `adjoint`, `substeps`), and the add-ons' parameters (`joint_damping`,
    ...) flat. A misspelt keyword is refused naming the closest of all these."""
    cls = type(self)
    for field, value in zip(dataclasses.fields(cls), fields, strict=False):
        if field.name in keywords:
            raise TypeError(f"{cls.__name__} got {field.name} both by position and by keyword")
        keywords[field.name] = value
    if len(fields) > len(dataclasses.fields(cls)):
        raise TypeError(f"{cls.__name__} takes at most {len(dataclasses.fields(cls))} positional fields")
    refuse_unknown(cls, keywords, inspect.signature(cls).parameters)
    for alias, name in cls.aliases:
        if alias in keywords:
            keywords[name] = keywords.pop(alias)
    fields = {field.name: field for field in dataclasses.fields(cls)}
    gather_dynamics(cls, fields, keywords)
    gather_integrator(fields, keywords)
    gather_addons(cls, keywords)
    assign_fields(self, keywords)
    for contact in getattr(self, "contacts", ()):
        contact.check(self.dynamics)
    check_friction(self)


def check_friction(env) -> None:
    """Refuse, by name, friction the step cannot integrate: on dynamics it cannot act on, more
    than one friction add-on, or friction beside located contacts."""
    friction = getattr(env, "friction", ())
    for addon in friction:
        addon.check(env.dynamics)
    if len(friction) > 1:
        raise ValueError(f"{type(env).__name__} takes at most one friction add-on, got {len(friction)}")
    if friction and getattr(env, "contacts", ()):
        raise ValueError(
            f"{type(env).__name__}: Coulomb friction and located contacts (restitution, walls) cannot be "
            "combined yet; give either the friction keywords or the contact ones"
        )


def gather_dynamics(cls, fields, keywords) -> None:
    """Move the dynamics' flat parameters (`pole_mass=0.2`) into a `dynamics` keyword."""
    field = fields.get("dynamics")
    factory = None if field is None else field.metadata.get("factory")
    if factory is None:
        return
    dynamics_class = getattr(factory, "func", factory)
    names = {f.name for f in dataclasses.fields(dynamics_class)} - set(fields)
    flat = {name: keywords.pop(name) for name in list(keywords) if name in names}
    if not flat:
        return
    if "dynamics" in keywords:
        raise TypeError(
            f"{cls.__name__}: give either dynamics= or its parameters ({', '.join(sorted(flat))}), not both"
        )
    keywords["dynamics"] = factory(**flat)


def gather_integrator(fields, keywords) -> None:
    """Build the `integrator` from the flat solver settings, if any are given."""
    settings = {name: keywords.pop(name) for name in INTEGRATOR_KEYWORDS if name in keywords}
    if not settings or "integrator" not in fields:
        keywords.update(settings)  # left for `assign_fields` to refuse by name
        return
    if "integrator" in keywords:
        raise TypeError(f"give either integrator= or solver settings ({', '.join(settings)}), not both")
    settings.setdefault("solver", fields["integrator"].metadata.get("solver", "euler"))
    keywords["integrator"] = make_integrator(settings.pop("solver"), **settings)


__all__ = ["INTEGRATOR_KEYWORDS", "construct_scene", "gather_dynamics", "gather_integrator", "integrator_keywords"]
