"""Registering the scenes with Gymnasium under the `lerax_like/` namespace."""

import functools

import gymnasium

from ._specs import SPECS


def _make_env(spec, **kwargs):
    from ._env import GymnasiumEnv

    return GymnasiumEnv(spec, **kwargs)


def _make_vector_env(spec, **kwargs):
    from ._vector import GymnasiumVectorEnv

    return GymnasiumVectorEnv(spec, **kwargs)


def register_envs() -> tuple[str, ...]:
    """Register every id of `SPECS` (every scene with a `GymnasiumSpec`); return the ids now registered.

    Called on `import lerax_like`. Idempotent: ids already in Gymnasium's registry are
    left as they are.
    """
    registered = []
    for spec in SPECS.values():
        if spec.id not in gymnasium.registry:
            gymnasium.register(
                id=spec.id,
                entry_point=functools.partial(_make_env, spec),
                vector_entry_point=functools.partial(_make_vector_env, spec),
                max_episode_steps=spec.max_episode_steps,
                reward_threshold=spec.reward_threshold,
            )
        registered.append(spec.id)
    return tuple(registered)


__all__ = ["register_envs"]
