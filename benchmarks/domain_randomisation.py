"""Domain randomisation: a policy trained over a batch of pole masses vs one trained on the nominal mass.

Both: MLP (2 x 32), Adam 3e-3, 1024 vmapped envs, 100-step rollouts, 100 iterations on the
smooth reward (thresholds at infinity). The randomised batch has per-env pole masses
uniform in [0.05, 0.2] (env parameters under `eqx.filter_vmap`). Evaluation: fraction of
100 random starts of the ordinary CartPoleContinuous balanced for 500 steps, per pole mass,
inside and outside the training range.

    python benchmarks/domain_randomisation.py   # writes benchmarks/results/domain_randomisation.json
"""

import json
import pathlib
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

jax.config.update("jax_enable_x64", True)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

import lerax_like as ll  # noqa: E402
from lerax_like.control.learning import MLPPolicy, episode_lengths, train_policy  # noqa: E402

INF = float("inf")
NUM_ENVS = 1024
MASSES = (0.01, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2)


def train(envs, env_axis, seed):
    start = time.perf_counter()
    policy, history = train_policy(
        envs, MLPPolicy(4, 1, width=32, key=jr.key(0)), key=jr.key(seed), num_envs=NUM_ENVS,
        horizon=100, iterations=100, learning_rate=3e-3, env_axis=env_axis,
    )
    return policy, float(history[-1]) / 100, time.perf_counter() - start


def main():
    masses = jr.uniform(jr.key(5), (NUM_ENVS,), minval=0.05, maxval=0.2)
    randomised_envs = eqx.filter_vmap(
        lambda m: ll.CartPoleContinuous(pole_mass=m, reward="smooth", theta_threshold_radians=INF, x_threshold=INF)
    )(masses)
    nominal_env = ll.CartPoleContinuous(reward="smooth", theta_threshold_radians=INF, x_threshold=INF)
    results = {}
    for name, envs, axis, seed in [("nominal", nominal_env, None, 1), ("randomised", randomised_envs, 0, 1), ("randomised_seed3", randomised_envs, 0, 3)]:
        policy, final_reward, seconds = train(envs, axis, seed)
        balanced = {
            str(m): float(jnp.mean(episode_lengths(ll.CartPoleContinuous(pole_mass=m), policy, key=jr.key(2), num_starts=100) >= 500))
            for m in MASSES
        }
        results[name] = {"training_seed": seed, "final_mean_reward_per_step": final_reward, "train_seconds": seconds, "balanced_fraction_by_pole_mass": balanced}
        print(name, json.dumps(results[name]), flush=True)
    out = pathlib.Path(__file__).parent / "results" / "domain_randomisation.json"
    out.write_text(json.dumps({"results": results, "training_masses": [0.05, 0.2], "jax": jax.__version__}, indent=1))


if __name__ == "__main__":
    main()
