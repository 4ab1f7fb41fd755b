"""Domain randomisation: a policy trained over a batch of pole masses vs one trained on the nominal mass.

The recipe is the notebook's (`notebooks/domain_randomisation.ipynb`, its cell tagged
`recipe`, run here as it stands there so that the two cannot drift apart):
an MLP (2 x 32) trained through the simulator on 256 vmapped CartPoleContinuous envs,
smooth reward minus a cost on the cart, thresholds at infinity, a horizon curriculum of
50, 100 and 200 steps (60, 30 and 30 Adam iterations). The randomised batch has per-env
pole masses uniform in [3, 8] kg (env parameters under `eqx.filter_vmap`), the nominal
one 0.1 kg. Evaluation: fraction of 100 random starts of the ordinary CartPoleContinuous
(12 degree and 2.4 m thresholds) balanced for 500 steps, per pole mass, inside and
outside the training range. Several training seeds, the same evaluation starts. For
reference, what the motor allows: a linear-quadratic regulator designed at each mass
(discrete Riccati equation of the Euler step linearised at upright; needs SciPy).

    python -m benchmarks domain_randomisation            # writes benchmarks/results/domain_randomisation.json
    python -m benchmarks domain_randomisation --quick    # one seed, 16 envs, three masses, into results/quick/
    python -m benchmarks.domain_randomisation [--seeds 1 2 3 4 5] [--num-envs 256] [--out DIR]
"""

import argparse
import json
import pathlib
import platform
import time
import types

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402  (after float64 is on)
from benchmarks import results_dir  # noqa: E402

NOTEBOOK = pathlib.Path(__file__).resolve().parents[1] / "notebooks" / "domain_randomisation.ipynb"

MASSES = (0.01, 0.1, 0.4, 1.0, 2.0, 2.5, 3.0, 4.0, 6.4, 8.0, 9.0, 10.0, 11.0, 12.8, 16.0)


def notebook_recipe() -> types.SimpleNamespace:
    """The names defined by the notebook's cell tagged `recipe` (constants, training, evaluation)."""
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    (source,) = ["".join(c["source"]) for c in cells if "recipe" in c.get("metadata", {}).get("tags", [])]
    namespace: dict = {}
    exec(compile(source, f"{NOTEBOOK}:recipe", "exec"), namespace)  # the cell holds its own imports
    return types.SimpleNamespace(**namespace)


class LinearPolicy(eqx.Module):
    gain: jax.Array

    def __call__(self, observation):
        return -self.gain @ observation


def lqr_policy(pole_mass: float) -> LinearPolicy:
    """Discrete LQR at `pole_mass`: state weights (1, 1, 10, 1), action weight 1."""
    import scipy.linalg

    env = ll.make("CartPoleContinuous", pole_mass=pole_mass)

    def vector_field(y, action):
        return env.dynamics.vector_field(0.0, y, env.physical_input(action))

    upright, no_action = jnp.zeros(4), jnp.zeros(1)
    dt = float(env.dt)
    a = np.eye(4) + dt * np.asarray(jax.jacfwd(vector_field, 0)(upright, no_action))
    b = dt * np.asarray(jax.jacfwd(vector_field, 1)(upright, no_action))
    q, r = np.diag([1.0, 1.0, 10.0, 1.0]), np.eye(1)
    p = scipy.linalg.solve_discrete_are(a, b, q, r)
    return LinearPolicy(jnp.asarray(np.linalg.solve(r + b.T @ p @ b, b.T @ p @ a)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="seed 1, 16 envs, pole masses 0.1, 4 and 10 kg")
    parser.add_argument("--seeds", type=int, nargs="+", default=None)
    parser.add_argument("--num-envs", type=int, default=None)
    parser.add_argument("--out", type=pathlib.Path, default=None, help="default: benchmarks/results[/quick]")
    args = parser.parse_args(argv)
    args.seeds = args.seeds or ([1] if args.quick else [1, 2, 3, 4, 5])
    args.num_envs = args.num_envs or (16 if args.quick else 256)
    masses = (0.1, 4.0, 10.0) if args.quick else MASSES
    out = (args.out or results_dir(args.quick)) / "domain_randomisation.json"
    dr = notebook_recipe()
    low, high = dr.TRAINING_MASS_RANGE
    runs = []
    for seed in args.seeds:
        # The same split as the notebook and the test.
        masses_key, randomised_key, nominal_key = jr.split(jr.key(seed), 3)
        pole_masses = jr.uniform(masses_key, (args.num_envs,), minval=low, maxval=high)
        for name, pole_mass, key in [("randomised", pole_masses, randomised_key), ("nominal", dr.NOMINAL_MASS, nominal_key)]:
            start = time.perf_counter()
            policy, histories = dr.train_balancing_policy(pole_mass, key=key, num_envs=args.num_envs)
            histories[-1].block_until_ready()
            seconds = time.perf_counter() - start
            balanced = dr.balanced_fractions(policy, masses, key=jr.key(2))
            run = {
                "policy": name, "seed": seed, "train_seconds": round(seconds, 1),
                "final_mean_reward_per_step": [round(float(h[-1]) / n, 4) for h, n in zip(histories, dr.HORIZONS)],
                "balanced_fraction_by_pole_mass": {str(m): f for m, f in balanced.items()},
            }
            runs.append(run)
            print(json.dumps(run), flush=True)
    lqr = {str(m): dr.balanced_fractions(lqr_policy(m), [m], key=jr.key(2))[m] for m in masses}
    print("lqr_per_mass", json.dumps(lqr), flush=True)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({
        "training_mass_range": list(dr.TRAINING_MASS_RANGE), "nominal_mass": dr.NOMINAL_MASS,
        "num_envs": args.num_envs, "horizons": list(dr.HORIZONS), "iterations": list(dr.ITERATIONS),
        "learning_rates": list(dr.LEARNING_RATES), "initial_spread": list(dr.INITIAL_SPREAD),
        "evaluation": "100 random starts of CartPoleContinuous (key 2), balanced = 500 steps",
        "jax": jax.__version__, "machine": f"{platform.machine()}, shared 2-core CPU (train_seconds include compilation)",
        "runs": runs, "lqr_per_mass": lqr,
    }, indent=1))


if __name__ == "__main__":
    main()
