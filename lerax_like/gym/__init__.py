"""The Gymnasium layer: `gymnasium.make("lerax_like/CartPole-v1")` and friends.

The only part of the package that imports gymnasium. On `import lerax_like` the ids of
`SPECS` (id -> `GymSpec`, every scene of `lerax_like.SCENES`) are registered, with string entry points naming the
creators of `lerax_like.gym.envs` (two per id: `CartPoleEnv` builds the `GymnasiumEnv` of
`gymnasium.make`, `CartPoleVectorEnv` the `GymnasiumVectorEnv` of
`gymnasium.make_vec(..., vectorization_mode="vector_entry_point")`).
"""

from ._batch import Batch as Batch, Outcome as Outcome
from ._env import GymnasiumEnv as GymnasiumEnv
from ._registration import register_envs as register_envs
from ._canvas import Canvas as Canvas
from ._renderers import (
    RENDERERS as RENDERERS,
    register_renderer as register_renderer,
    render_frame as render_frame,
)
from ._specs import GymnasiumSpec as GymnasiumSpec, GymSpec as GymSpec, SPECS as SPECS
from ._vector import GymnasiumVectorEnv as GymnasiumVectorEnv
from . import envs as envs


__all__ = ["Batch", "Canvas", "GymSpec", "GymnasiumSpec", "GymnasiumEnv", "GymnasiumVectorEnv", "Outcome", "SPECS", "envs", "RENDERERS", "register_envs", "register_renderer", "render_frame"]
