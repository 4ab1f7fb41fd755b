"""Rollouts with the env batch axis sharded over devices give the unsharded results.

XLA fixes the number of host devices when JAX starts, so the sharded run happens in a
fresh interpreter with `XLA_FLAGS=--xla_force_host_platform_device_count=4` set before
`jax` is imported; it prints the largest differences from the unsharded run as JSON.
"""

import json
import os
import pathlib
import subprocess
import sys

import pytest


ROOT = pathlib.Path(__file__).resolve().parents[1]

PROGRAM = r"""
import json

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np
from jax.sharding import NamedSharding, PartitionSpec

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import lerax_like

NUM_ENVS, NUM_STEPS = 8, 30
assert jax.device_count() == 4, jax.devices()
mesh = jax.make_mesh((4,), ("envs",), axis_types=(jax.sharding.AxisType.Auto,))
batch = NamedSharding(mesh, PartitionSpec("envs"))


def episode(env, key):
    # env.step with autoreset and random actions: the throughput workload.
    reset_key, key = jr.split(key)
    state, _, _ = env.reset(key=reset_key)

    def body(carry, _):
        state, key = carry
        key, action_key, step_key = jr.split(key, 3)
        action = env.action_space.sample(key=action_key)
        state, observation, reward, terminated, truncated, info = env.step(state, action, key=step_key)
        return (state, key), (observation, reward, terminated, info["solver_steps"])

    _, outputs = jax.lax.scan(body, (state, key), None, length=NUM_STEPS)
    return outputs


def transitions(env, y0, actions, key):
    # lerax_like.rollout: transition only, what gradient-based control differentiates.
    state = lerax_like.EnvState(y=y0, steps=jnp.zeros((), dtype=int))
    return lerax_like.rollout(env, state, actions, key=key)


def max_difference(a, b):
    return max(
        float(np.max(np.abs(np.asarray(x, dtype=np.float64) - np.asarray(y, dtype=np.float64))))
        for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b))
    )


def spread(tree):
    # Every output leaf must really live on the four devices.
    return min(len(leaf.sharding.device_set) for leaf in jax.tree.leaves(tree))


results = {}
keys = jr.split(jr.key(0), NUM_ENVS)
for solver in ("euler", "tsit5"):
    # One env per batch element, pole masses differing: the parameters are batched too.
    pole_masses = jnp.linspace(0.05, 0.4, NUM_ENVS)
    envs = eqx.filter_vmap(lambda m: lerax_like.make("CartPoleContinuous", pole_mass=m, solver=solver))(pole_masses)
    run = eqx.filter_jit(eqx.filter_vmap(episode))
    unsharded = run(envs, keys)
    envs_sharded, keys_sharded = eqx.filter_shard((envs, keys), batch)
    sharded = run(envs_sharded, keys_sharded)
    results[f"{solver} step, NamedSharding"] = [max_difference(unsharded, sharded), spread(sharded)]
    if solver != "euler":
        continue

    # shard_map takes arrays only: the solver's functions and static fields stay outside.
    env_arrays, env_static = eqx.partition(envs_sharded, eqx.is_array)

    def local_episodes(env_arrays, keys):
        return eqx.filter_vmap(episode)(eqx.combine(env_arrays, env_static), keys)

    # check_vma=False: equinox's `error_if` (inside diffeqsolve) builds a `lax.cond`
    # whose branches JAX's varying-manual-axes check finds mismatched (JAX 0.10).
    run_shard_map = jax.jit(
        jax.shard_map(
            local_episodes,
            mesh=mesh,
            in_specs=PartitionSpec("envs"),
            out_specs=PartitionSpec("envs"),
            check_vma=False,
        )
    )
    via_shard_map = run_shard_map(env_arrays, keys_sharded)
    results[f"{solver} step, shard_map"] = [max_difference(unsharded, via_shard_map), spread(via_shard_map)]

    y0 = jr.uniform(jr.key(1), (NUM_ENVS, 4), minval=-0.2, maxval=0.2)
    actions = jr.uniform(jr.key(2), (NUM_ENVS, NUM_STEPS, 1), minval=-1.0, maxval=1.0)
    roll = eqx.filter_jit(eqx.filter_vmap(transitions))
    unsharded = roll(envs, y0, actions, keys)
    sharded = roll(envs_sharded, *eqx.filter_shard((y0, actions), batch), keys_sharded)
    results[f"{solver} rollout, NamedSharding"] = [max_difference(unsharded, sharded), spread(sharded)]

print("RESULTS" + json.dumps(results))
"""


@pytest.mark.slow
def test_sharded_rollouts_match_unsharded():
    environment = {**os.environ, "XLA_FLAGS": "--xla_force_host_platform_device_count=4", "JAX_PLATFORMS": "cpu"}
    completed = subprocess.run(
        [sys.executable, "-c", PROGRAM], cwd=ROOT, env=environment, capture_output=True, text=True, timeout=600
    )
    assert completed.returncode == 0, completed.stderr[-4000:]
    line = next(line for line in completed.stdout.splitlines() if line.startswith("RESULTS"))
    results = json.loads(line.removeprefix("RESULTS"))
    assert len(results) == 4
    for name, (difference, devices) in results.items():
        assert devices == 4, f"{name}: outputs on {devices} devices, not sharded over 4"
        # The same float64 program on each shard: identical up to XLA's fusion of
        # multiply-adds, which can differ between the partitioned and whole programs.
        assert difference <= 1e-12, f"{name}: sharded and unsharded differ by {difference}"
