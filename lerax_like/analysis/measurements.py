"""What a study measures of one solver setting: the trajectories, their dense output, the
cost in vector-field evaluations, the clock's floor, and the drift of conserved quantities.
"""

import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..env import AbstractEnv, EnvState, episode_time
from ..integrate import solver_facts
from ..physics import AbstractConservativeDynamics


def _trajectory(env: AbstractEnv, y0, inputs):
    # The env's own integration (`evolve`, the core of every env step), with the physical
    # input given directly, so that a zero force can be studied on a scene whose actions
    # cannot express one (CartPole pushes left or right).
    def body(state, u):
        next_state, info = env.evolve(state, u)
        outputs = (next_state.y, info["solver_ok"], info["solver_steps"], info["solver_rejected_steps"])
        return next_state, outputs

    state = EnvState(y=y0, steps=jnp.zeros((), dtype=int))
    _, (ys, ok, steps, rejected) = jax.lax.scan(body, state, inputs)
    return ys, ok, steps, rejected


@eqx.filter_jit
def batched_trajectories(env: AbstractEnv, y0s, inputs):
    """`(ys, solver_ok, accepted steps, rejected steps)` of every initial state in `y0s`
    under the physical `inputs` (one per env step), each of shape `(B, T, ...)`."""
    return jax.vmap(_trajectory, in_axes=(None, 0, None))(env, y0s, inputs)


def timed_runs(env: AbstractEnv, y0s, inputs, repeats: int):
    """The outputs of `batched_trajectories` and the seconds of each of `repeats` runs
    after a compiling one (`block_until_ready` on each)."""
    outputs = jax.block_until_ready(batched_trajectories(env, y0s, inputs))  # compiles
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        outputs = jax.block_until_ready(batched_trajectories(env, y0s, inputs))
        times.append(time.perf_counter() - start)
    return tuple(np.asarray(x) for x in outputs), times


def failure_reason(env: AbstractEnv, ys: np.ndarray, ok: np.ndarray, inputs) -> str:
    """Why a batch of trajectories failed, in words, from its first failed env step.

    `ys` `(B, T, n)` and `ok` `(B, T)` as `batched_trajectories` returns them: a failed
    step keeps its pre-step state, so the failed solve is rerun from `ys[b, k]` and asked
    why (`Integrator.failure`). `""` if no step failed.
    """
    failed = np.argwhere(~np.asarray(ok, dtype=bool))
    if len(failed) == 0:
        return ""
    b, k = (int(i) for i in failed[0])
    where = f"at env step {k} of trajectory {b}"
    if getattr(env, "contacts", ()):
        return f"hybrid step failed {where} (a segment's solve, an unlocated event, or more impacts than max_events)"
    physics = env.physics
    start = jnp.asarray(ys[b, k])
    reason = env.integrator.failure(
        physics.vector_field, start, jnp.asarray(inputs[k]), env.dt,
        projection=env.project if env.projects_state() else None,
        velocity_indices=physics.velocity_indices,
        t0=episode_time(k, env.dt),
    )
    # A solve that succeeds alone but failed in the batch: the rerun's rounding differs.
    return f"{reason or 'solve failed (not reproduced alone)'} {where}"


def evaluations_per_step(solver: diffrax.AbstractSolver) -> tuple[int, int, int] | None:
    """`(per accepted step, per rejected step, once per solve)` vector-field evaluations,
    as `lerax_like.solver_facts` counts them; `None` for implicit solvers, whose count
    depends on the root finder."""
    facts = solver_facts(solver)
    counts = facts.evaluations_per_step, facts.evaluations_per_rejected_step, facts.evaluations_per_solve
    per_step, per_rejected_step, per_solve = counts
    if per_step is None or per_rejected_step is None or per_solve is None:  # all None or none
        return None
    return per_step, per_rejected_step, per_solve


@eqx.filter_jit
def _batched_dense_states(env: AbstractEnv, starts, inputs, ts):
    """The solver's dense output inside every env step, shape `(B, T, len(ts), n)`.

    Env step `k` of trajectory `b` restarts from `starts[b, k]`, the solver's own state
    after the step before, as the trajectory did (`env.evolve`): the same solve, saved
    inside.
    """
    physics = env.physics

    def one_step(y0, u, k):
        return env.integrator.dense_states(
            physics.vector_field, y0, u, env.dt, ts,
            projection=env.project if env.projects_state() else None,
            velocity_indices=physics.velocity_indices,
            t0=episode_time(k, env.dt),
        )

    def trajectory(y_starts):
        ks = jnp.arange(inputs.shape[0])
        return jax.lax.map(lambda args: one_step(*args), (y_starts, inputs, ks))

    return jax.vmap(trajectory)(starts)


def dense_errors(
    env, y0s, ys: np.ndarray, inputs, fractions: np.ndarray, reference: np.ndarray, reference_inside: np.ndarray
) -> dict[str, float] | None:
    """`l2_error` and `linf_error` over the dense grid: every env-step end and the points inside.

    As DiffEqDevTools' `L2` and `Linf`: the root mean square (over grid points and state
    components) and the maximum of the error; each maximal over the batch. The step ends
    are the trajectory's own states, so `linf_error >= max_error`. `reference` holds the
    reference at the step ends `(B, T, n)`, `reference_inside` at the `fractions` of each
    step `(B, T, m - 1, n)`. None if a dense solve failed.
    """
    dt = float(env.dt)
    if len(fractions) == 0:
        inside_errors = np.zeros(ys.shape[:2] + (0, ys.shape[-1]))
    else:
        starts = np.concatenate([np.asarray(y0s)[:, None], ys[:, :-1]], axis=1)
        states, ok = _batched_dense_states(env, jnp.asarray(starts), inputs, jnp.asarray(fractions * dt))
        if not bool(np.all(np.asarray(ok))):
            return None
        inside_errors = np.asarray(states) - reference_inside  # (B, T, m - 1, n)
    boundary_errors = ys - reference  # (B, T, n)
    grid = np.concatenate([inside_errors, boundary_errors[:, :, None]], axis=2)  # (B, T, m, n)
    squared = np.mean(grid.reshape(grid.shape[0], -1) ** 2, axis=1)
    return {"l2_error": float(np.sqrt(np.max(squared))), "linf_error": float(np.max(np.abs(grid)))}


def empty_call_seconds(y0s, repeats: int = 20) -> float:
    """The time of a compiled call that does nothing: a timing below a few of these is unresolved."""
    identity = jax.jit(lambda y: y)
    jax.block_until_ready(identity(y0s))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(identity(y0s))
        times.append(time.perf_counter() - start)
    return min(times)


def conserved_quantities(dynamics) -> tuple[str, ...]:
    """The invariants of `dynamics` under zero input that a study measures the drift of.

    Energy only where the dynamics claim to conserve it (`AbstractConservativeDynamics`
    whose `conserves_energy` holds: no damper among its add-ons, no equations that drop
    a term); a damped scene's energy falls by physics, and its fall is no solver error.
    Momentum wherever the dynamics define it.
    """
    names = []
    if isinstance(dynamics, AbstractConservativeDynamics) and dynamics.conserves_energy:
        names.append("energy")
    if getattr(dynamics, "momentum", None) is not None:
        names.append("momentum")
    return tuple(names)


def invariant_drifts(dynamics, ys: np.ndarray, y0s: np.ndarray) -> dict[str, float]:
    """Maximum over trajectory and batch of `|I(y_t) - I(y_0)|` for each of the
    `conserved_quantities` of `dynamics`, as `{"energy_drift": ..., "momentum_drift": ...}`."""
    drifts = {}
    for name in conserved_quantities(dynamics):
        invariant = getattr(dynamics, name)
        along = np.asarray(jax.vmap(jax.vmap(invariant))(jnp.asarray(ys)))
        start = np.asarray(jax.vmap(invariant)(jnp.asarray(y0s)))
        drifts[f"{name}_drift"] = float(np.max(np.abs(along - start[:, None])))
    return drifts
