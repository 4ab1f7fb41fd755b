"""What the Gymnasium layer knows of each registered id: read off the scenes in `SCENES`.

A scene that declares a `GymnasiumSpec` (`CartPole.gymnasium`) is registered as
`lerax_like/<name>`. Its start is drawn from the scene's own `initial_bounds`, with NumPy
in the order of Gymnasium's calls, so that a seed gives Gymnasium's start; its renderer
is Gymnasium's env class, fed the scene's state and the attributes the spec maps.
"""

import dataclasses
import operator
from typing import Any

import numpy as np
from gymnasium.envs.classic_control import utils as classic_utils

from ..env import AbstractEnv, GymnasiumSpec
from ..scenes import SCENES


@dataclasses.dataclass(frozen=True)
class GymSpec:
    """One registered id: `lerax_like/<name>` stands in for Gymnasium's `<name>`."""

    scene: type[AbstractEnv]

    @property
    def declared(self) -> GymnasiumSpec:
        return self.scene.gymnasium

    @property
    def name(self) -> str:
        return self.declared.name

    @property
    def id(self) -> str:
        return f"lerax_like/{self.name}"

    @property
    def max_episode_steps(self) -> int:
        return self.declared.max_episode_steps

    @property
    def reward_threshold(self) -> float | None:
        return self.declared.reward_threshold

    @property
    def renderer(self) -> str:
        return self.declared.renderer

    def initial_state(self, bounds, np_random, options: dict[str, Any] | None, num_envs: int) -> np.ndarray:
        """Starts as Gymnasium's env draws them with `np_random` (same calls, same order),
        within `bounds`, the scene's `initial_bounds` in NumPy: float64 of shape `(n, num_envs)`.

        Only the coordinates whose bounds differ are drawn (a car at rest is not). Gymnasium
        draws `uniform(size=(k,))` for one env and `uniform(size=(k, num_envs))` for its
        vector CartPole; both consume the generator in the same order.
        """
        low, high = bounds
        drawn = low != high
        if options is None and self.declared.reset_options == "bounds" and not self.declared.float32_start and drawn.all():
            # Every coordinate drawn within its bounds (CartPole): the draws below, in short.
            return low[:, None] + (high - low)[:, None] * np_random.random((low.size, num_envs))
        state = np.repeat(low[:, None], num_envs, axis=1)
        low, high = low[drawn], high[drawn]
        if self.declared.reset_options == "pendulum":
            if options is not None:
                x = classic_utils.verify_number_and_cast(options.get("x_init", high[0]))
                y = classic_utils.verify_number_and_cast(options.get("y_init", high[1]))
                high = np.array([x, y])
            low = -high
        elif options is not None:
            # Gymnasium's `low`/`high` options bound every drawn coordinate alike.
            new_low, new_high = classic_utils.maybe_parse_reset_bounds(options, low.min(), high.max())
            low, high = np.full_like(low, new_low), np.full_like(high, new_high)
        # `np_random.uniform(low, high, size)` computes `low + (high - low) * random()` per
        # draw: the same numbers, without its slow broadcasting of array bounds (the
        # vector envs draw at every step where an episode ends).
        if drawn.sum() == 1:  # one value per env, as Gymnasium's mountain cars draw it
            draws = low + (high - low) * np_random.random((num_envs,))
        else:
            draws = low[:, None] + (high - low)[:, None] * np_random.random((low.size, num_envs))
        if self.declared.float32_start:
            draws = draws.astype(np.float32)
        state[drawn] = np.reshape(draws, (-1, num_envs))
        return state

    def render_sync(self, renderer, scene: AbstractEnv, state: np.ndarray, action) -> None:
        """Prepare Gymnasium's renderer: our state and the spec's attributes."""
        renderer.state = state
        for gymnasium_name, path in self.declared.attributes:
            if hasattr(renderer, gymnasium_name):
                setattr(renderer, gymnasium_name, float(np.asarray(operator.attrgetter(path)(scene))))
        # Pendulum draws the clipped torque of the last step as an arrow (none after reset);
        # its renderer has no `last_u` before its own reset, which it never sees here, so
        # the attribute is set on every renderer (the others ignore it).
        renderer.last_u = None if action is None else float(np.asarray(scene.physical_input(action))[0])


SPECS: dict[str, GymSpec] = {
    spec.id: spec for spec in (GymSpec(scene) for scene in SCENES.values() if scene.gymnasium is not None)
}
"""All ids the layer registers, by id."""
