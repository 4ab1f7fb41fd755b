"""gymnax's `Environment` interface over every registered scene, for pure-JAX trainers.

    env, params = lerax_like.gymnax.make("CartPole-v1", solver="rk4")
    obs, state = env.reset(key, params)
    obs, state, reward, done, info = env.step(key, state, action, params)  # gymnax 0.0.x
    obs, state, reward, terminated, truncated, info = env.step(key, state, action, params)  # gymnax 1.x

Made as gymnax makes its own envs: `make` returns the env and its `default_params`, and
the env subclasses gymnax's `Environment`, whose `step` is `step_env` followed by a reset
when the episode ends (gymnax's autoreset, in whichever gymnax is installed: 0.0.9, which
rejax needs, returns five values; 1.x returns six). `params` (a `Params`) holds the
scene's array leaves (masses, lengths, `dt`, thresholds: what `jax.grad` differentiates and
`jax.vmap` batches, as gymnax's params) and the episode limit `max_steps_in_episode`, as
data. The env itself holds only what decides code paths (the solver, the action kind), so
it is hashable, as trainers that mark it static need.

gymnax is imported when `make` is first called (`pip install 'lerax_like[gymnax]'`).
"""

from typing import TYPE_CHECKING

from ._make import make as make, registered_envs as registered_envs
from ._params import Params as Params

if TYPE_CHECKING:  # made on first use (`__getattr__`), once gymnax is imported
    from ._environment import Environment as Environment


def __getattr__(name: str):
    # The Environment class subclasses gymnax's, so it exists only once gymnax is imported.
    if name == "Environment":
        from ._make import environment_class

        return environment_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["Environment", "Params", "make", "registered_envs"]
