"""One episode with every solver preset: final-state error against SciPy, and wall time."""

import time
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr
import numpy as np

from ..env import rollout
from ..integrate import SOLVERS, make_integrator
from .reference import reference_trajectories
from .scenes import make, reference_method


@eqx.filter_jit
def _rollout(env, state, actions, key):
    return rollout(env, state, actions, key=key)


def preset_rollouts(
    scene: str = "CartPole", *, steps: int = 200, seed: int = 0, repeats: int = 3,
    presets: Sequence[str] = SOLVERS.names, reference_tolerance: float = 1e-13,
) -> list[dict[str, Any]]:
    """Roll out one episode of `steps` seeded random actions with each solver preset.

    The actions and initial state come from `seed`; the episode runs through
    `lerax_like.rollout` (no termination, no reset). Each row holds the preset, the
    max-norm error of the final state against SciPy's `solve_ivp` (DOP853, Radau for
    stiff scenes, `rtol = atol = reference_tolerance`), the wall time of the compiled
    rollout (minimum of `repeats`) and the solver steps taken.
    """
    with jax.enable_x64(True):
        env = make(scene)
        initial_key, action_key, rollout_key = jr.split(jr.key(seed), 3)
        state = env.initial(key=initial_key)
        actions = jax.vmap(lambda k: env.action_space.sample(key=k))(jr.split(action_key, steps))
        inputs = np.asarray(jax.vmap(env.physical_input)(actions))
        method = reference_method(scene)
        reference = reference_trajectories(
            env.dynamics, np.asarray(state.y)[None], inputs, float(env.dt),
            method=method, rtol=reference_tolerance, atol=reference_tolerance,
        )[0, -1]
        rows = []
        for preset in presets:
            preset_env = eqx.tree_at(lambda e: e.integrator, env, make_integrator(preset))
            ys, infos = jax.block_until_ready(_rollout(preset_env, state, actions, rollout_key))
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                ys, infos = jax.block_until_ready(_rollout(preset_env, state, actions, rollout_key))
                times.append(time.perf_counter() - start)
            rows.append({
                "scene": scene,
                "solver": preset,
                "controller": type(preset_env.integrator.stepsize_controller).__name__,
                "final_error": float(jnp.max(jnp.abs(ys[-1] - reference))),
                "seconds": min(times),
                "steps": int(jnp.sum(infos["solver_steps"])),
                "solver_ok": bool(jnp.all(infos["solver_ok"])),
                "reference": f"{method} rtol=atol={reference_tolerance:g}",
            })
    return rows


def format_rollouts(rows: list[dict[str, Any]]) -> str:
    header = ("solver", "controller", "final error", "seconds", "steps", "ok")
    lines = [header] + [
        (r["solver"], r["controller"], f"{r['final_error']:.2e}", f"{r['seconds']:.2e}", str(r["steps"]), str(r["solver_ok"]))
        for r in rows
    ]
    widths = [max(len(line[i]) for line in lines) for i in range(len(header))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines)
