"""Registering the scenes with Gymnasium under the `lerax_like/` namespace."""

import gymnasium

from ._specs import SPECS


def register_envs() -> tuple[str, ...]:
    """Register every id of `SPECS` (one per scene of `lerax_like.SCENES`); return the ids now registered.

    The entry points are strings naming the creators of `lerax_like.gym.envs`, as Gymnasium's
    own ids name its env classes. Called on `import lerax_like`. Idempotent: ids already in Gymnasium's
    registry are left as they are.
    """
    from .envs import entry_points

    registered = []
    for spec in SPECS.values():
        if spec.id not in gymnasium.registry:
            entry_point, vector_entry_point = entry_points(spec.id)
            gymnasium.register(
                id=spec.id,
                entry_point=entry_point,
                vector_entry_point=vector_entry_point,
                max_episode_steps=spec.max_episode_steps,
                reward_threshold=spec.reward_threshold,
            )
        registered.append(spec.id)
    return tuple(registered)
