"""What the Gymnasium layer knows of each registered id: a table keyed by scene class.

Every scene of `lerax_like.SCENES` (when `lerax_like` is imported) is registered as
`lerax_like/<name>`. A scene that stands for a Gymnasium env has a `GymnasiumSpec` in
`GYMNASIUM_SPECS` (`CartPole: GymnasiumSpec("CartPole-v1", ...)`), and its id is
Gymnasium's name; the others are `lerax_like/<scene class>-v0`, with the scene's own
episode length. The scenes themselves know nothing of Gymnasium: its names (`masspole`),
renderers and start conventions live here. The start is drawn from the scene's own
`initial_bounds`, with NumPy in the order of Gymnasium's calls, so that a seed gives
Gymnasium's start.
"""

import dataclasses
import functools
import math
import operator
from typing import Any, Literal

import numpy as np
from gymnasium.envs.classic_control import utils as classic_utils

from ..env import AbstractEnv
from ..scenes import SCENES


@dataclasses.dataclass(frozen=True)
class GymnasiumSpec:
    """What registers a scene as `lerax_like/<name>` in Gymnasium, standing in for Gymnasium's `<name>`.

    - `name`: Gymnasium's id (`"CartPole-v1"`); `max_episode_steps`, `reward_threshold`: Gymnasium's.
    - `renderer`: the Gymnasium env class (`"module:Class"`) whose `render` draws the scene;
      None for lerax_like's own picture of it (`lerax_like.gym.RENDERERS`).
    - `attributes`: Gymnasium's attribute names on its env and the scene's path for each
      (`("masspole", "dynamics.pole_mass")`; a name listed twice when Gymnasium's one
      attribute is several parameters, as Acrobot's `LINK_MOI`). The renderer reads them,
      and the Gymnasium envs have them as attributes that users read and write.
    - `reset_options`: how Gymnasium's `reset(options=...)` bounds the start: `"bounds"`
      (`low`/`high` for every drawn coordinate) or `"pendulum"` (`x_init`, `y_init`).
    - `float32_start`: Gymnasium's env stores its start in float32 (Acrobot).
    """

    name: str
    max_episode_steps: int | None
    reward_threshold: float | None
    renderer: str | None = None
    attributes: tuple[tuple[str, str], ...] = ()
    reset_options: Literal["bounds", "pendulum"] = "bounds"
    float32_start: bool = False


_CLASSIC = "gymnasium.envs.classic_control"
_CARTPOLE_ATTRIBUTES = (
    ("gravity", "dynamics.gravity"),
    ("masscart", "dynamics.cart_mass"),
    ("masspole", "dynamics.pole_mass"),
    ("length", "dynamics.half_length"),
    ("force_mag", "force_mag"),
    ("tau", "dt"),
    ("theta_threshold_radians", "theta_threshold_radians"),
    ("x_threshold", "x_threshold"),
)


def _road_attributes(engine: str) -> tuple[tuple[str, str], ...]:
    """Gymnasium's attribute names on its mountain cars: the same as the scenes' own."""
    names = ("min_position", "max_position", "max_speed", "goal_position", "goal_velocity", engine)
    return (("gravity", "dynamics.gravity"), *((name, name) for name in names))


GYMNASIUM_SPECS: dict[type[AbstractEnv], GymnasiumSpec] = {
    SCENES["CartPole"]: GymnasiumSpec(
        name="CartPole-v1",
        max_episode_steps=500,
        reward_threshold=475.0,
        renderer=f"{_CLASSIC}.cartpole:CartPoleEnv",
        attributes=_CARTPOLE_ATTRIBUTES,
    ),
    SCENES["Pendulum"]: GymnasiumSpec(
        name="Pendulum-v1",
        max_episode_steps=200,
        reward_threshold=None,
        renderer=f"{_CLASSIC}.pendulum:PendulumEnv",
        attributes=(
            ("g", "dynamics.gravity"),
            ("m", "dynamics.mass"),
            ("l", "dynamics.length"),
            ("max_speed", "max_speed"),
            ("max_torque", "max_torque"),
            ("dt", "dt"),
        ),
        reset_options="pendulum",
    ),
    SCENES["Acrobot"]: GymnasiumSpec(
        name="Acrobot-v1",
        max_episode_steps=500,
        reward_threshold=-100.0,
        renderer=f"{_CLASSIC}.acrobot:AcrobotEnv",
        attributes=(
            ("dt", "dt"),
            ("LINK_LENGTH_1", "dynamics.link_length_1"),
            ("LINK_MASS_1", "dynamics.link_mass_1"),
            ("LINK_MASS_2", "dynamics.link_mass_2"),
            ("LINK_COM_POS_1", "dynamics.link_com_position_1"),
            ("LINK_COM_POS_2", "dynamics.link_com_position_2"),
            # Gymnasium's one moment of inertia is both links'.
            ("LINK_MOI", "dynamics.link_moment_of_inertia_1"),
            ("LINK_MOI", "dynamics.link_moment_of_inertia_2"),
            ("MAX_VEL_1", "max_velocity_1"),
            ("MAX_VEL_2", "max_velocity_2"),
        ),
        float32_start=True,
    ),
    SCENES["MountainCar"]: GymnasiumSpec(
        name="MountainCar-v0",
        max_episode_steps=200,
        reward_threshold=-110.0,
        renderer=f"{_CLASSIC}.mountain_car:MountainCarEnv",
        attributes=_road_attributes("force"),
    ),
    SCENES["MountainCarContinuous"]: GymnasiumSpec(
        name="MountainCarContinuous-v0",
        max_episode_steps=999,
        reward_threshold=90.0,
        renderer=f"{_CLASSIC}.continuous_mountain_car:Continuous_MountainCarEnv",
        attributes=_road_attributes("power"),
    ),
}
"""Scene class -> what registers it with Gymnasium. A scene standing for a Gymnasium env adds a line here."""

# Observations are float32: a start bound beyond float32's range gives an infinite one.
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def _bound(options: dict[str, Any], name: str, default: float) -> float:
    """`options[name]` (or `default`) as a float, refused by name unless finite and within float32's range."""
    value = classic_utils.verify_number_and_cast(options.get(name, default))
    if not (math.isfinite(value) and abs(value) <= _FLOAT32_MAX):
        raise ValueError(
            f"reset option {name!r} must be a finite number within float32's range "
            f"(|{name}| <= {_FLOAT32_MAX:.4g}), got {value!r}"
        )
    return value


def _within(low: np.ndarray, high: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """Uniform draws `unit` (shape `(n, num_envs)`) mapped into the bounds, as
    `np_random.uniform(low, high)` maps them: `low + (high - low) * unit`, the same numbers."""
    return low[:, None] + (high - low)[:, None] * unit


def _own_spec(scene: type[AbstractEnv]) -> GymnasiumSpec:
    """The id of a scene that stands for no Gymnasium env: `<scene class>-v0`, its
    episode length the scene's default, drawn by lerax_like's own renderer."""
    defaults: dict[str, Any] = {field.name: field.default for field in dataclasses.fields(scene)}
    return GymnasiumSpec(
        name=f"{scene.__name__}-v0", max_episode_steps=defaults.get("max_episode_steps"), reward_threshold=None
    )


@dataclasses.dataclass(frozen=True)
class GymSpec:
    """One registered id: `lerax_like/<name>`, standing in for Gymnasium's `<name>` where
    `stands_for_gymnasium`."""

    scene: type[AbstractEnv]

    @property
    def declared(self) -> GymnasiumSpec:
        declared = GYMNASIUM_SPECS.get(self.scene)
        return _own_spec(self.scene) if declared is None else declared

    @functools.cached_property
    def attribute_paths(self) -> dict[str, tuple[str, ...]]:
        """Gymnasium's attribute names on its env -> the scene's paths each stands for (two for
        Acrobot's `LINK_MOI`, both links' moment of inertia)."""
        paths: dict[str, tuple[str, ...]] = {}
        for gymnasium_name, path in self.declared.attributes:
            paths[gymnasium_name] = (*paths.get(gymnasium_name, ()), path)
        return paths

    @property
    def stands_for_gymnasium(self) -> bool:
        """Whether the id stands for Gymnasium's env of the same name (and is tested against it)."""
        return self.scene in GYMNASIUM_SPECS

    @property
    def name(self) -> str:
        return self.declared.name

    @property
    def id(self) -> str:
        return f"lerax_like/{self.name}"

    @property
    def max_episode_steps(self) -> int | None:
        return self.declared.max_episode_steps

    @property
    def reward_threshold(self) -> float | None:
        return self.declared.reward_threshold

    @property
    def renderer(self) -> str | None:
        return self.declared.renderer

    def initial_state(self, bounds, np_random, options: dict[str, Any] | None, num_envs: int) -> np.ndarray:
        """Starts as Gymnasium's env draws them with `np_random` (same calls, same order),
        within `bounds`, the scene's `initial_bounds` in NumPy: float64 of shape `(n, num_envs)`.

        Only the coordinates whose bounds differ are drawn (a car at rest is not). Gymnasium
        draws `uniform(size=(k,))` for one env and `uniform(size=(k, num_envs))` for its
        vector CartPole; both consume the generator in the same order.
        """
        low, high = bounds
        if self._uniform_start(bounds, options):
            return _within(low, high, np_random.random((low.size, num_envs)))
        drawn = low != high
        state = np.repeat(low[:, None], num_envs, axis=1)
        low, high = low[drawn], high[drawn]
        if self.declared.reset_options == "pendulum":
            if options is not None:
                high = np.array([_bound(options, "x_init", high[0]), _bound(options, "y_init", high[1])])
            low = -high
        elif options is not None:
            # Gymnasium's `low`/`high` options bound every drawn coordinate alike.
            new_low, new_high = classic_utils.maybe_parse_reset_bounds(
                {name: _bound(options, name, 0.0) for name in ("low", "high") if name in options},
                low.min(),
                high.max(),
            )
            low, high = np.full_like(low, new_low), np.full_like(high, new_high)
        # `np_random.uniform(low, high, size)` computes `low + (high - low) * random()` per
        # draw: the same numbers, without its slow broadcasting of array bounds (the
        # vector envs draw at every step where an episode ends).
        if drawn.sum() == 1:  # one value per env, as Gymnasium's mountain cars draw it
            draws = low + (high - low) * np_random.random((num_envs,))
        else:
            draws = _within(low, high, np_random.random((low.size, num_envs)))
        if self.declared.float32_start:
            draws = draws.astype(np.float32)
        state[drawn] = np.reshape(draws, (-1, num_envs))
        return state

    def initial_state_each(self, bounds, generators, options) -> np.ndarray:
        """One start from each generator with its options, shape `(n, len(generators))`:
        the numbers of `initial_state(bounds, generator, option, 1)` for each in turn.

        SB3's envs restart one generator each; where the starts are uniform draws within
        the bounds, only the draws are per env and the scaling is done once for all.
        """
        low, high = bounds
        if all(option is None for option in options) and self._uniform_start(bounds, None):
            unit = np.concatenate([generator.random((low.size, 1)) for generator in generators], axis=1)
            return _within(low, high, unit)
        columns = [self.initial_state(bounds, generator, option, 1) for generator, option in zip(generators, options)]
        return np.concatenate(columns, axis=1)

    def _uniform_start(self, bounds, options: dict[str, Any] | None) -> bool:
        """Whether a start is every coordinate drawn uniformly within its bounds, as
        Gymnasium's CartPole draws it (no options, none fixed, no float32 rounding)."""
        declared = self.declared
        low, high = bounds
        return (
            options is None and declared.reset_options == "bounds" and not declared.float32_start
            and bool((low != high).all())
        )

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


_SCENES_WITH_IDS = (*GYMNASIUM_SPECS, *(scene for scene in SCENES.values() if scene not in GYMNASIUM_SPECS))
SPECS: dict[str, GymSpec] = {spec.id: spec for spec in (GymSpec(scene) for scene in _SCENES_WITH_IDS)}
"""All ids the layer registers, by id: one per scene of `SCENES` (those standing for
Gymnasium's envs first)."""
