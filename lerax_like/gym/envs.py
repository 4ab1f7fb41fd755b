"""The registry's string entry points: one `EnvCreator` per registered id and kind, found by name.

`gymnasium.make("lerax_like/CartPole-v1")` calls `lerax_like.gym.envs:CartPoleEnv`, and
`gymnasium.make_vec(..., vectorization_mode="vector_entry_point")` calls
`lerax_like.gym.envs:CartPoleVectorEnv`, as Gymnasium's own id names
`gymnasium.envs.classic_control.cartpole:CartPoleEnv`. A string entry point is what
Gymnasium's machinery expects: the spec serialises (`EnvSpec.to_json`), compares equal
after `make`, and pickles. An `EnvCreator`'s `metadata` is what `gymnasium.make` reads to
add `RenderCollection` for `render_mode="rgb_array_list"` or `HumanRendering`.
"""

from typing import Any

from ._env import GymnasiumEnv
from ._render import render_fps
from ._specs import SPECS, GymSpec
from ._vector import GymnasiumVectorEnv


class EnvCreator:
    """`env_class` of one registered id: `creator(**keywords)` is `env_class(spec, **keywords)`,
    and `metadata` is the class's with the id's `render_fps`."""

    def __init__(self, env_class: type[GymnasiumEnv] | type[GymnasiumVectorEnv], spec: GymSpec):
        self.env_class = env_class
        self.spec = spec
        self.metadata = {**env_class.metadata, "render_fps": render_fps(spec)}

    def __call__(self, **keywords: Any) -> GymnasiumEnv | GymnasiumVectorEnv:
        return self.env_class(self.spec, **keywords)

    def __repr__(self) -> str:
        return f"EnvCreator({self.env_class.__name__}, {self.spec.id!r})"


_KINDS = {"Env": GymnasiumEnv, "VectorEnv": GymnasiumVectorEnv}
CREATORS: dict[str, EnvCreator] = {
    f"{spec.scene.__name__}{kind}": EnvCreator(env_class, spec)
    for spec in SPECS.values()
    for kind, env_class in _KINDS.items()
}
"""Entry point name (`CartPoleEnv`, `CartPoleVectorEnv`) -> its creator."""


def __getattr__(name: str) -> EnvCreator:
    # The entry points' names, looked up as Gymnasium's `load_env_creator` does: `getattr(module, name)`.
    try:
        return CREATORS[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None


def entry_points(env_id: str) -> tuple[str, str]:
    """The string entry point and vector entry point of `env_id`, as registered."""
    name = SPECS[env_id].scene.__name__
    return f"{__name__}:{name}Env", f"{__name__}:{name}VectorEnv"


__all__ = ["CREATORS", "EnvCreator", "entry_points"]
