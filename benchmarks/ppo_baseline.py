"""PPO (Stable-Baselines3) on the same task as the policy-learning notebook, for comparison.

Task: `CartPoleContinuous` (Gymnasium's rules: +1 a step, the episode ends when the pole
passes 12 degrees or the cart leaves the track, 500 steps at most). Success: the share of
100 random starts that a trained policy keeps up for all 500 steps, the same criterion as
`notebooks/policy_learning.ipynb`. Records env steps, wall time and that share.

    pip install stable-baselines3   # with a CPU torch; not a dependency of lerax_like
    python -m benchmarks ppo_baseline            # 200000 env steps, 100 evaluation starts
    python -m benchmarks ppo_baseline --quick    # 2048 env steps (one PPO rollout), 10 starts
    python -m benchmarks.ppo_baseline [--timesteps 200000] [--out DIR]

Writes ppo_baseline.json into benchmarks/results/ (results/quick/ with --quick).
"""

import argparse
import json
import pathlib
import platform
import time

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np

import lerax_like as ll
from benchmarks import results_dir
from lerax_like.env import EnvState


class CartPoleContinuousGym(gymnasium.Env):
    """`lerax_like.CartPoleContinuous` (Euler, float64) behind Gymnasium's single-env API."""

    def __init__(self):
        with jax.enable_x64(True):
            self._env = ll.CartPoleContinuous()
            self._transition = jax.jit(
                lambda env, y, action: env.transition(EnvState(y=y, steps=jnp.zeros((), int)), action, key=jax.random.key(0))[0].y
            )
            self._terminal = jax.jit(lambda env, y: env.terminal(EnvState(y=y, steps=jnp.zeros((), int)), key=jax.random.key(0)))
        high = np.array([4.8, np.inf, 0.42, np.inf], dtype=np.float32)
        self.observation_space = gymnasium.spaces.Box(-high, high, dtype=np.float32)
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, (1,), dtype=np.float32)
        self._steps = 0

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self._y = self.np_random.uniform(-0.05, 0.05, size=(4,))
        self._steps = 0
        return self._y.astype(np.float32), {}

    def step(self, action):
        with jax.enable_x64(True):
            y = self._transition(self._env, jnp.asarray(self._y), jnp.asarray(action, dtype=jnp.float64))
            terminated = bool(self._terminal(self._env, y))
        self._y = np.asarray(y)
        self._steps += 1
        return self._y.astype(np.float32), 1.0, terminated, self._steps >= 500, {}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2048 env steps, 10 evaluation starts")
    parser.add_argument("--timesteps", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    arguments = parser.parse_args(argv)
    try:
        from stable_baselines3 import PPO
    except ImportError as error:
        raise SystemExit("ppo_baseline needs Stable-Baselines3: pip install stable-baselines3") from error
    timesteps = arguments.timesteps or (2048 if arguments.quick else 200_000)
    num_starts = 10 if arguments.quick else 100

    env = CartPoleContinuousGym()
    model = PPO("MlpPolicy", env, seed=arguments.seed, verbose=0, device="cpu")
    start = time.perf_counter()
    model.learn(total_timesteps=timesteps)
    seconds = time.perf_counter() - start

    evaluation = CartPoleContinuousGym()
    lengths = []
    for episode in range(num_starts):
        observation, _ = evaluation.reset(seed=10_000 + episode)
        for t in range(500):
            action, _ = model.predict(observation, deterministic=True)
            observation, _, terminated, truncated, _ = evaluation.step(action)
            if terminated or truncated:
                break
        lengths.append(t + 1)
    lengths = np.array(lengths)
    record = {
        "algorithm": "PPO (stable-baselines3 defaults, MlpPolicy, 1 env)",
        "env_steps": timesteps,
        "train_seconds": seconds,
        "evaluation_starts": num_starts,
        "balanced_500": int(np.sum(lengths >= 500)),
        "mean_episode_length": float(lengths.mean()),
        "seed": arguments.seed,
        "date": time.strftime("%Y-%m-%d"),
        "machine": f"{platform.machine()}, {platform.processor() or 'cpu'}, 2 cores shared",
    }
    out = (arguments.out or results_dir(arguments.quick)) / "ppo_baseline.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
