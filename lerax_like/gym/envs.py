"""One Gymnasium env class per registered id: the registry's string entry points.

`gymnasium.make("lerax_like/CartPole-v1")` builds `lerax_like.gym.envs:CartPoleEnv`, and
`gymnasium.make_vec(..., vectorization_mode="vector_entry_point")` builds
`lerax_like.gym.envs:CartPoleVectorEnv`, as Gymnasium's own id names
`gymnasium.envs.classic_control.cartpole:CartPoleEnv`. A string entry point is what
Gymnasium's machinery expects: the spec serialises (`EnvSpec.to_json`), compares equal
after `make`, and pickles; and the class's `metadata` is what `gymnasium.make` reads to add
`RenderCollection` for `render_mode="rgb_array_list"` or `HumanRendering`.

The classes are generated from `SPECS` (every scene of `lerax_like.SCENES`), named after
the scene. Each also has Gymnasium's attributes of its env
(`gravity`, `masscart`, `length`, `tau`, `x_threshold` on CartPole; `g`, `m`, `l`,
`max_speed` on Pendulum; ...: `GymnasiumSpec.attributes`) as properties. Reading one gives
the scene's parameter; writing one replaces that leaf of the scene (`eqx.tree_at`), checked
as the scene's constructor checks it, and so changes the physics from the next step on, as
in Gymnasium; the parameters are an argument of the compiled step, so nothing recompiles.
"""

import dataclasses
import functools
import operator
from typing import Any

import equinox as eqx
import numpy as np

from .._fields import as_parameter
from .._module_attributes import generated_names
from ._compiled import float64
from ._env import GymnasiumEnv
from ._render import render_fps
from ._specs import SPECS, GymSpec
from ._vector import GymnasiumVectorEnv


def _replace(scene, path: str, value, name: str):
    """`scene` with the leaf at `path` replaced by `value`, refused by Gymnasium's `name`
    if the parameter's own constructor refuses it (range, type, checks across fields)."""
    *owner_path, field_name = path.split(".")
    owner = functools.reduce(getattr, owner_path, scene)
    old = getattr(owner, field_name)
    new = as_parameter(value, name).astype(old.dtype)
    if new.shape != old.shape:
        raise ValueError(f"{name} must have shape {old.shape}, got {new.shape}")
    # `eqx.tree_at` skips the constructor's checks: run them on a copy built by keyword.
    values = {field.name: getattr(owner, field.name) for field in dataclasses.fields(owner) if field.init}
    try:
        type(owner)(**{**values, field_name: new})
    except (TypeError, ValueError) as error:
        raise type(error)(f"{name} (the scene's {path}): {error}") from error
    return eqx.tree_at(operator.attrgetter(path), scene, new)


def _attribute(name: str, paths: tuple[str, ...]) -> property:
    def get(self) -> float:
        with float64():
            return float(np.asarray(operator.attrgetter(paths[0])(self.scene)))

    def set(self, value) -> None:
        with float64():
            scene = self.scene
            for each in paths:
                scene = _replace(scene, each, value, name)
            self.scene = scene

    where = " and ".join(f"`scene.{each}`" for each in paths)
    return property(get, set, doc=f"Gymnasium's `{name}`: {where}, readable and writable.")


def _env_classes(spec: GymSpec) -> tuple[type, type]:
    name = spec.scene.__name__
    paths: dict[str, tuple[str, ...]] = {}
    for gymnasium_name, path in spec.declared.attributes:  # a name may map to several paths
        paths[gymnasium_name] = (*paths.get(gymnasium_name, ()), path)
    attributes = {gymnasium_name: _attribute(gymnasium_name, each) for gymnasium_name, each in paths.items()}
    if spec.stands_for_gymnasium:
        doc = (
            f"`gymnasium.make({spec.id!r})`: `lerax_like.{name}` behind Gymnasium's `{spec.name}` "
            f"(see `GymnasiumEnv`), with Gymnasium's attributes {', '.join(attributes) or 'none'}."
        )
    else:
        doc = f"`gymnasium.make({spec.id!r})`: `lerax_like.{name}` as a Gymnasium env (see `GymnasiumEnv`)."

    def env_init(self, render_mode: str | None = None, **scene_kwargs: Any):
        GymnasiumEnv.__init__(self, spec, render_mode=render_mode, **scene_kwargs)

    env = type(
        f"{name}Env",
        (GymnasiumEnv,),
        {
            "__init__": env_init,
            "__module__": __name__,
            "__doc__": doc,
            "metadata": {**GymnasiumEnv.metadata, "render_fps": render_fps(spec)},
            **attributes,
        },
    )

    def vector_init(self, num_envs: int = 1, max_episode_steps: int | None = None, render_mode: str | None = None, **scene_kwargs: Any):
        GymnasiumVectorEnv.__init__(
            self, spec, num_envs=num_envs, max_episode_steps=max_episode_steps, render_mode=render_mode, **scene_kwargs
        )

    vector_doc = doc.replace(f"gymnasium.make({spec.id!r})", f"gymnasium.make_vec({spec.id!r}, num_envs)").replace(
        "GymnasiumEnv", "GymnasiumVectorEnv"
    )
    vector = type(
        f"{name}VectorEnv",
        (GymnasiumVectorEnv,),
        {
            "__init__": vector_init,
            "__module__": __name__,
            "__doc__": vector_doc,
            "metadata": {**GymnasiumVectorEnv.metadata, "render_fps": render_fps(spec)},
            **attributes,
        },
    )
    for cls in (env, vector):
        cls.__init__.__name__ = "__init__"
        cls.__init__.__qualname__ = f"{cls.__name__}.__init__"
    return env, vector


ENV_CLASSES: dict[str, tuple[type, type]] = {spec.id: _env_classes(spec) for spec in SPECS.values()}
"""Id -> (env class, vector env class)."""

_BY_NAME = {cls.__name__: cls for classes in ENV_CLASSES.values() for cls in classes}
# Generated, one pair per id: found by name as the string entry points and pickle look them up.
__getattr__ = generated_names(__name__, _BY_NAME)


def entry_points(env_id: str) -> tuple[str, str]:
    """The string entry point and vector entry point of `env_id`, as registered."""
    env, vector = ENV_CLASSES[env_id]
    return f"{__name__}:{env.__name__}", f"{__name__}:{vector.__name__}"


# The env classes are generated, one pair per registered id: there is no static list of them to declare.
__all__ = ["ENV_CLASSES", "entry_points", *_BY_NAME]  # pyright: ignore[reportUnsupportedDunderAll]
