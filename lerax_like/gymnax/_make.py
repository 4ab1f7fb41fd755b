"""`make`: a gymnax env and its params from a Gymnasium id or a scene name."""

import functools

from ..gym import SPECS
from ..scenes import SCENES
from ..scenes import make as make_scene


_INSTALL_HINT = (
    "lerax_like.gymnax needs gymnax: pip install 'lerax_like[gymnax]' (gymnax 0.0.9, which rejax "
    "needs; gymnax 1.x works too)"
)


def _scene_classes() -> dict[str, type]:
    """Gymnasium ids (`"CartPole-v1"`) and scene names (`"CartPole"`) -> scene class."""
    classes = {spec.name: spec.scene for spec in SPECS.values()}
    classes.update(SCENES)
    return classes


def registered_envs() -> tuple[str, ...]:
    """The names `make` takes: the Gymnasium ids of the scenes that have one, then every scene's name."""
    return tuple(_scene_classes())


@functools.cache
def environment_class() -> type:
    """`lerax_like.gymnax.Environment`, importing gymnax (with an install hint if it is missing)."""
    try:
        import gymnax  # noqa: F401
    except ImportError as error:
        raise ImportError(_INSTALL_HINT) from error
    from ._environment import Environment

    return Environment


def make(name: str, **keywords):
    """`(env, params)` as `gymnax.make(name)` returns them, for a scene built with `keywords`.

    `name` is a Gymnasium id (`"CartPole-v1"`) or a scene name (`"CartPole"`,
    `"DoubleCartPole"`); `keywords` are the scene's (`solver="rk4"`, `pole_mass=0.2`,
    `max_episode_steps=200`). `params` is `env.default_params`.
    """
    classes = _scene_classes()
    if name not in classes:
        raise ValueError(f"unknown env {name!r}; lerax_like.gymnax.make takes one of: {', '.join(classes)}")
    scene = make_scene(classes[name], **keywords)
    env = environment_class()(scene, name=name)
    return env, env.default_params
