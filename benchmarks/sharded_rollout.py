"""Env rollouts sharded over every device of every process: the multi-host recipe, runnable.

The env batch axis is laid over a one-axis mesh of all devices (`jax.devices()`, across
processes once `jax.distributed` is initialised). Keys are made inside a jitted function
with `out_shardings`, so each device computes only its own envs' keys and no process
needs the whole batch in memory; the vmapped rollout then runs where its inputs live.

One process (any number of local devices; on CPU force some to see the sharding; the runner
`python -m benchmarks sharded_rollout [--quick]` forces four):

    XLA_FLAGS=--xla_force_host_platform_device_count=4 python -m benchmarks.sharded_rollout

Several processes (one per host, or several on one machine to try it): the same command
on each, with the coordinator's address, the number of processes and this one's rank
(on SLURM or Cloud TPU `jax.distributed.initialize()` finds them itself):

    python -m benchmarks.sharded_rollout --coordinator HOST:1234 --num-processes 2 --process-id 0
    python -m benchmarks.sharded_rollout --coordinator HOST:1234 --num-processes 2 --process-id 1

It prints the mean number of episodes ended per env (random actions, autoreset; the same on every process) and, on process 0,
the largest difference from the same rollout run unsharded on process 0's first device, which it
also writes to sharded_rollout.json (in benchmarks/results/, or results/quick/ with --quick).
"""

import functools

import jax

from benchmarks import benchmark_parser, output_folder


def main(argv=None):
    parser = benchmark_parser(__doc__, quick="8 envs per device, 50 steps")
    parser.add_argument("--coordinator", default=None, help="HOST:PORT of process 0")
    parser.add_argument("--num-processes", type=int, default=None)
    parser.add_argument("--process-id", type=int, default=None)
    parser.add_argument("--envs-per-device", type=int, default=None)
    parser.add_argument("--steps", type=int, default=None)
    args = parser.parse_args(argv)
    args.envs_per_device = args.envs_per_device or (8 if args.quick else 256)
    args.steps = args.steps or (50 if args.quick else 500)

    if args.coordinator is not None:
        # CPU processes exchange data with gloo; GPUs and TPUs need no setting.
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
        jax.distributed.initialize(args.coordinator, args.num_processes, args.process_id)

    import jax.numpy as jnp
    import jax.random as jr
    import numpy as np
    from jax.experimental import multihost_utils
    from jax.sharding import NamedSharding, PartitionSpec

    import lerax_like
    from lerax_like.analysis.recording import write_record

    env = lerax_like.make("CartPole", solver="rk4")
    num_envs = args.envs_per_device * jax.device_count()
    mesh = jax.make_mesh((jax.device_count(),), ("envs",), axis_types=(jax.sharding.AxisType.Auto,))
    batch = NamedSharding(mesh, PartitionSpec("envs"))

    def episode(key):
        reset_key, key = jr.split(key)
        state, _, _ = env.reset(key=reset_key)

        def body(carry, _):
            state, key, total = carry
            key, action_key, step_key = jr.split(key, 3)
            action = env.action_space.sample(key=action_key)
            state, _, _, terminated, truncated, _ = env.step(state, action, key=step_key)
            return (state, key, total + (terminated | truncated)), None

        (_, _, episodes), _ = jax.lax.scan(body, (state, key, jnp.zeros((), dtype=int)), None, length=args.steps)
        return episodes

    @functools.partial(jax.jit, out_shardings=batch)
    def make_keys(seed):
        return jr.split(jr.key(seed), num_envs)

    @jax.jit
    def episodes_ended(keys):
        return jax.vmap(episode)(keys)

    keys = make_keys(0)
    sharded = episodes_ended(keys)  # sharded like `keys`: each device runs its own envs
    mean_episodes = float(jnp.mean(sharded))  # a global reduction, the same on every process
    print(f"process {jax.process_index()}/{jax.process_count()}: {num_envs} envs on {jax.device_count()} devices "
          f"({len(sharded.sharding.device_set)} hold the result), mean episodes ended per env {mean_episodes:.4f}", flush=True)

    gathered = np.asarray(multihost_utils.process_allgather(sharded, tiled=True))
    if jax.process_index() == 0:
        with jax.default_device(jax.local_devices()[0]):
            local_keys = jr.split(jr.key(0), num_envs)
            unsharded = np.asarray(jax.jit(jax.vmap(episode))(local_keys))
        difference = float(np.max(np.abs(gathered - unsharded)))
        print(f"largest difference from the unsharded run: {difference}")
        write_record({
            "processes": jax.process_count(), "devices": jax.device_count(), "num_envs": num_envs,
            "steps": args.steps, "mean_episodes_ended_per_env": mean_episodes,
            "largest_difference_from_unsharded": difference,
        }, output_folder(args) / "sharded_rollout.json")


if __name__ == "__main__":
    main()
