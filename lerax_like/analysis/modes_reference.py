"""SciPy reference solutions of a hybrid scene: each mode solved by `solve_ivp`, each guard an event.

For a scene whose step is a hybrid system other than plain impacts (`env.modes(t0)`: Coulomb
stick-slip, contacts with friction, the disk on its floor), the studies' reference integrates
each env step mode by mode, as `hybrid_reference` does through plain impacts: `solve_ivp`
(DOP853 by default) in the mode's vector field, every guard a terminal event (falling through
zero), restarted at the earliest located one, where the system's own `settle`, told which guard
fired, applies its reset (an impact map, a switch) and picks the next mode. The modes, guards and
resets are the package's; the integrator and the event location are SciPy's (the references
typed from the equations in `tests/test_rolling_disk.py` and `tests/test_contact_friction.py`
check this one). A guard that starts at zero and rises (the switch just taken) is no event for
SciPy (a falling crossing needs a value >= 0 before and <= 0 after).

`modes_reference_gradient` differentiates a loss of these trajectories by central differences:
the gradient study's reference for such a scene, which owes nothing to automatic
differentiation or to diffrax's root find.
"""

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

from ..gradients import selection_spec
from ..hybrid import Surfaces
from .hybrid_reference import segmented_trajectories
from .reference import scipy_solve_ivp


class ModesStep(NamedTuple):
    """One env step of the reference: its end state `y`; its `events`, each `(time in the step, index
    of the guard that fell in the system's guards)`; each segment's `solve_ivp` solution."""

    y: np.ndarray
    events: list[tuple[float, int]]
    segments: list[Any]


class _Programs(NamedTuple):
    """A hybrid system's vector field, guards and settle, each a `jax.jit` of the system's
    arrays (a flat list) and the call's own arguments."""

    field: Callable
    guards: Callable
    settle: Callable


# Compiled once for every system of a structure: the system's arrays (its parameters, the
# step's `t0`) are arguments, so that a perturbed parameter (central differences) compiles
# nothing new. Plain `jax.jit` of the arrays as one list, where `eqx.filter_jit` of the system
# split it into arrays and the rest at every call: SciPy calls the field and the guards tens of
# thousands of times a rollout, and that split was most of each call's time (about 650 us a
# call for the sliding block, 16 us now). The same programs, so the same values.
@functools.cache
def _programs(static, treedef) -> _Programs:
    def system(arrays):
        return eqx.combine(jax.tree.unflatten(treedef, arrays), static)

    return _Programs(
        field=jax.jit(lambda arrays, t, y, u, mode: system(arrays).vector_field(t, y, (u, mode))),
        guards=jax.jit(lambda arrays, t, y, u, mode: system(arrays).guards(t, y, (u, mode))),
        settle=jax.jit(lambda arrays, t, y, u, mode, fired: system(arrays).settle(t, y, u, mode, fired)),
    )


def _compiled(modes) -> tuple[list, _Programs]:
    """`modes`' arrays and its programs (`_programs`)."""
    arrays, static = eqx.partition(modes, eqx.is_array)
    leaves, treedef = jax.tree.flatten(arrays)
    return leaves, _programs(static, treedef)


def reference_modes(env, t0: float = 0.0):
    """`env.modes(t0)` (its hybrid system at the episode's time `t0`), its arrays in float64."""
    env = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64) if eqx.is_inexact_array(leaf) else leaf, env)
    return env.modes(t0)


def uses_modes_reference(env) -> bool:
    """Whether the studies take this reference for `env`: a hybrid scene other than plain
    impacts, which `hybrid_reference` solves with its own events and maps."""
    modes = env.modes()
    return modes is not None and not isinstance(modes, Surfaces)


def modes_reference_step(
    modes, y0, u, dt: float, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
    dense_output: bool = False,
) -> ModesStep:
    """One env step `[0, dt]` from `y0` under the input `u` through every located event.

    `modes` as `reference_modes(env, t0)` returns them (call under `jax.enable_x64`). A
    failed check of the system's `settle` (a slip that no friction force makes consistent,
    Painleve's case; a rest the step does not model), a failed solve, or more events than
    its `max_events` raise `RuntimeError`: a reference never hides a failure.
    """
    solve_ivp = scipy_solve_ivp()
    arrays, programs = _compiled(modes)
    u = jnp.asarray(u, jnp.float64)
    y = jnp.asarray(y0, jnp.float64)
    mode = modes.initial_mode(y)
    count = int(np.size(programs.guards(arrays, jnp.asarray(0.0), y, u, mode)))
    t, fired = 0.0, np.zeros(count, bool)
    located: list[tuple[float, int]] = []
    segments = []
    for _ in range(modes.max_events + 1):
        y, mode, _, checks = programs.settle(arrays, jnp.asarray(t), jnp.asarray(y), u, mode, jnp.asarray(fired))
        failed = [name for name, passed in checks.items() if not bool(passed)]
        if failed:
            raise RuntimeError(f"modes reference: {', '.join(failed)} failed at t = {t} in the step")
        # SciPy asks each event in turn at the same point: the guards, computed once.
        last: dict[tuple, np.ndarray] = {}

        def guards(s, state, mode=mode) -> np.ndarray:
            key = (float(s), state.tobytes())
            if key not in last:
                last.clear()
                last[key] = np.asarray(programs.guards(arrays, s, state, u, mode))
            return last[key]

        events = []
        for i in range(count):
            def event(s, state, i=i, guards=guards):
                return float(guards(s, state)[i])

            event.terminal, event.direction = True, -1
            events.append(event)
        solution = solve_ivp(
            lambda s, state, mode=mode: np.asarray(programs.field(arrays, s, state, u, mode)), (t, dt), np.asarray(y),
            method=method, rtol=rtol, atol=atol, events=events, dense_output=dense_output,
        )
        if solution.status == -1:
            raise RuntimeError(f"modes reference solve ({method}) failed at t = {t} in the step: {solution.message}")
        segments.append(solution)
        hits = [(float(solution.t_events[i][0]), i) for i in range(count) if len(solution.t_events[i])]
        if not hits:
            return ModesStep(np.asarray(solution.y[:, -1]), located, segments)
        t, which = min(hits)
        located.append((t, which))
        y, fired = solution.y_events[which][0], np.arange(count) == which
    raise RuntimeError(f"modes reference: more than {modes.max_events} events in one step")


def modes_reference_trajectories(
    env, y0s, inputs, dt: float, fractions, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """As `dense_reference_trajectories`, through the located events of the env's hybrid system:
    one `modes_reference_step` per initial state and env step (the field read at the episode's
    time `k dt + s`), as `segmented_trajectories` returns them."""
    with jax.enable_x64(True):
        steps = [reference_modes(env, np.float64(k) * np.float64(dt)) for k in range(len(inputs))]

        def step(k: int, y, u):
            solved = modes_reference_step(
                steps[k], y, u, dt, method=method, rtol=rtol, atol=atol, dense_output=len(fractions) > 0
            )
            return solved.y, solved.segments

        return segmented_trajectories(step, y0s, inputs, dt, fractions)


def modes_reference_gradient(
    env, where: Callable, y0, inputs, cost: Callable, *, relative_step: float = 1e-3, rtol: float = 1e-13,
) -> dict[str, Any]:
    """The gradient of `cost(ys)` over the reference trajectory from `y0` under `inputs`, by central differences.

    Differentiated are the inexact leaves under `where(env)` (flattened as
    `jax.flatten_util.ravel_pytree` orders them), each by the fourth-order stencil
    `(f(x - 2h) - 8 f(x - h) + 8 f(x + h) - f(x + 2h)) / (12 h)` with `h = relative_step
    max(|x|, 1)`: its truncation error `h^4 f^(5) / 30` sits below the reference's own
    noise (`rtol / h`, about 1e-10 at the defaults). Returns `gradient` and `floor`, the
    relative change of the gradient when every `h` is doubled (the points at `+-2h` are
    shared, so it costs two more rollouts per parameter; it bounds both errors of the
    finer stencil, whose truncation is 16 times smaller), with `relative_step` and `rtol`.
    A step that the reference cannot take (a perturbed parameter that reaches Painleve's
    case) raises `RuntimeError`.
    """
    inputs = np.asarray(inputs, dtype=np.float64)
    with jax.enable_x64(True):
        params, static = eqx.partition(env, selection_spec(env, where))
        flat, unravel = ravel_pytree(jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64), params))
        flat = np.asarray(flat)
        dt = float(env.dt)

        def loss(x) -> float:
            perturbed = eqx.combine(unravel(jnp.asarray(x)), static)
            y0s = np.asarray(y0)[None]
            states, _ = modes_reference_trajectories(perturbed, y0s, inputs, dt, [], rtol=rtol, atol=rtol)
            return float(cost(jnp.asarray(states[0])))

        def at(i: int, h: float) -> float:
            return loss(flat + h * np.eye(flat.size)[i])

        gradient, doubled = np.empty_like(flat), np.empty_like(flat)
        for i in range(flat.size):
            h = relative_step * max(abs(flat[i]), 1.0)
            f = {n: at(i, n * h) for n in (-4, -2, -1, 1, 2, 4)}
            gradient[i] = (f[-2] - 8 * f[-1] + 8 * f[1] - f[2]) / (12 * h)
            doubled[i] = (f[-4] - 8 * f[-2] + 8 * f[2] - f[4]) / (24 * h)
    norm = float(np.linalg.norm(gradient))
    return {
        "gradient": gradient.tolist(),
        "floor": float(np.linalg.norm(doubled - gradient) / norm) if norm > 0 else float(np.linalg.norm(doubled)),
        "relative_step": relative_step,
        "rtol": rtol,
    }


__all__ = [
    "ModesStep", "modes_reference_gradient", "modes_reference_step", "modes_reference_trajectories", "reference_modes",
    "uses_modes_reference",
]
