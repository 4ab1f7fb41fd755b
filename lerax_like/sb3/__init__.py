"""Stable-Baselines3 vector envs over the compiled, batched step (optional: `pip install "lerax_like[sb3]"`).

`make_vec_env("lerax_like/CartPole-v1", n_envs=8, seed=0)` stands in for SB3's own
`make_vec_env("CartPole-v1", n_envs=8, seed=0)`: an SB3 `VecEnv` with SB3's semantics,
whose step is one compiled call for all envs instead of `DummyVecEnv`'s loop over single
envs. Importing this module does not import SB3; calling into it does.
"""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # imported on first use (`__getattr__`), so that importing this module needs no SB3
    from ._vec_env import CompiledVecEnv as CompiledVecEnv, EnvView as EnvView, MonitoredVecEnv as MonitoredVecEnv


def _sb3():
    try:
        from . import _vec_env
    except ImportError as error:
        if error.name is not None and error.name.split(".")[0] in ("stable_baselines3", "torch"):
            raise ImportError(
                "lerax_like.sb3 needs Stable-Baselines3: pip install \"lerax_like[sb3]\" (for a CPU-only "
                "PyTorch, install torch from https://download.pytorch.org/whl/cpu first)"
            ) from error
        raise
    return _vec_env


def make_vec_env(env_id: str, n_envs: int = 1, seed: int | None = None, **options: Any):
    """A monitored SB3 `VecEnv` of `n_envs` copies of the registered id `env_id`, stepped together.

    Mirrors `stable_baselines3.common.env_util.make_vec_env`: the same arguments, seeds
    (`seed + i` for env `i` at the first reset, the action space seeded with
    `seed + start_index`), `env_kwargs` as `gymnasium.make` takes them (scene keywords,
    `max_episode_steps`, `render_mode`, which defaults to `"rgb_array"` as in SB3), and
    episode statistics in the infos (`MonitoredVecEnv`, SB3's `VecMonitor` that answers
    `env_is_wrapped(Monitor)` with True as SB3's monitored envs do; writing to `monitor_dir` if given;
    `monitor_kwargs` may hold `info_keywords`). The result steps as SB3's `DummyVecEnv` of
    `gymnasium.make(env_id)` envs (see `CompiledVecEnv`, also for `inline_dispatch`). `dtype`
    is the precision of the step (`"float64"`, Gymnasium's, or `"float32"`).

    Not supported, as they act on single envs: `wrapper_class`/`wrapper_kwargs` (wrap the
    result in an SB3 `VecEnvWrapper` instead) and `vec_env_cls`/`vec_env_kwargs` (the
    batch is the vector env).
    """
    # The keywords (start_index, monitor_dir, env_kwargs, monitor_kwargs, dtype, ...) are
    # SB3's; `_vec_env.make_vec_env` spells them out and checks them.
    return _sb3().make_vec_env(env_id, n_envs=n_envs, seed=seed, **options)


def __getattr__(name: str):
    if name in ("CompiledVecEnv", "EnvView", "MonitoredVecEnv"):
        return getattr(_sb3(), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["CompiledVecEnv", "EnvView", "MonitoredVecEnv", "make_vec_env"]
