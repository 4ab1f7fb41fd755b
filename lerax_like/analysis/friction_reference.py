"""SciPy reference solutions through Coulomb stick-slip: each mode solved by `solve_ivp`, each switch an event.

For a scene with a friction add-on (`env.friction`, `lerax_like.physics.friction`), the studies'
reference integrates each env step mode by mode, as `hybrid_reference` does through impacts:
`solve_ivp` (DOP853 by default) in the mode's vector field with the mode's conditions as
terminal `events` (falling through zero), restarted at the first located one in the next mode.
The modes, their fields, their conditions and the rule for the next mode are the package's
(`lerax_like.stick_slip.FrictionModes`); what is independent is the integrator and the event
location. A condition that starts at zero and rises (the switch just taken) is no event for
SciPy (a falling crossing needs a value >= 0 before and <= 0 after).

`friction_reference_gradient` differentiates a loss of these reference trajectories by
central differences: the gradient study's reference for a scene with friction, which owes
nothing to automatic differentiation or to diffrax's root find.
"""

from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import numpy as np


class FrictionStep(NamedTuple):
    """One env step of the reference: the state at its end, the located switches, the segments.

    `switches` holds `(time in the step, which condition fell)`, the condition's index in
    `FrictionModes.guards` (`SLIP_ENDS`, `NORMAL_FLIPS`, `RELEASE`, `INCONSISTENT`);
    `segments` each segment's `solve_ivp` solution (dense if asked).
    """

    y: np.ndarray
    switches: list[tuple[float, int]]
    segments: list[Any]


# Compiled once for every env of a structure: the modes (parameters, the step's `t0`) are
# arguments, so that a perturbed parameter (central differences) compiles nothing new.
@eqx.filter_jit
def _field(modes, t, y, u, mode):
    return modes.vector_field(t, y, (u, mode))


@eqx.filter_jit
def _guards(modes, t, y, u, mode):
    return modes.guards(t, y, (u, mode))


@eqx.filter_jit
def _settle(modes, t, y, u, mode, fired):
    return modes.settle(t, y, u, mode, fired)


def friction_modes(env):
    """The `FrictionModes` of `env`'s friction add-on, its arrays in float64."""
    import jax
    import jax.numpy as jnp

    from ..stick_slip import FrictionModes

    modes = FrictionModes(physics=env.physics, dynamics=env.dynamics, friction=env.friction[0])
    return jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64) if eqx.is_inexact_array(leaf) else leaf, modes)


def friction_reference_step(
    modes, y0, u, dt: float, t0: float = 0.0, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
    dense_output: bool = False,
) -> FrictionStep:
    """One env step `[0, dt]` from `y0` under the input `u`, the field read at `t0 + s`, through every switch.

    `modes` as `friction_modes(env)` returns them (call under `jax.enable_x64`). A slip
    that no friction force makes consistent (Painleve), a failed solve, or more switches
    than the add-on's `max_events` raise `RuntimeError`: a reference never hides a failure.
    """
    import jax.numpy as jnp

    solve_ivp = _solve_ivp()
    modes = eqx.tree_at(lambda m: m.t0, modes, jnp.asarray(t0, jnp.float64))
    u = jnp.asarray(u, jnp.float64)
    y = jnp.asarray(y0, jnp.float64)
    t, mode, fired = 0.0, (jnp.zeros(()), jnp.ones(())), np.zeros(4, bool)
    switches: list[tuple[float, int]] = []
    segments = []
    for _ in range(modes.friction.max_events + 1):
        y, mode, _, checks = _settle(modes, jnp.asarray(t), jnp.asarray(y), u, mode, jnp.asarray(fired))
        if not bool(checks["friction_consistent"]):
            raise RuntimeError(f"friction reference: no consistent slip at t = {t0 + t} (Painleve)")
        # SciPy asks each event in turn at the same point: the four conditions, computed once.
        last: dict[tuple, np.ndarray] = {}

        def conditions(s, state, mode=mode) -> np.ndarray:
            key = (float(s), state.tobytes())
            if key not in last:
                last.clear()
                last[key] = np.asarray(_guards(modes, s, state, u, mode))
            return last[key]

        events = []
        for i in range(4):
            def event(s, state, i=i, conditions=conditions):
                return float(conditions(s, state)[i])

            event.terminal, event.direction = True, -1
            events.append(event)
        solution = solve_ivp(
            lambda s, state, mode=mode: np.asarray(_field(modes, s, state, u, mode)), (t, dt), np.asarray(y),
            method=method, rtol=rtol, atol=atol, events=events, dense_output=dense_output,
        )
        if solution.status == -1:
            raise RuntimeError(f"friction reference solve ({method}) failed at t={t0 + t}: {solution.message}")
        segments.append(solution)
        hits = [(float(solution.t_events[i][0]), i) for i in range(4) if len(solution.t_events[i])]
        if not hits:
            return FrictionStep(np.asarray(solution.y[:, -1]), switches, segments)
        t, which = min(hits)
        switches.append((t, which))
        y, fired = solution.y_events[which][0], np.arange(4) == which
    raise RuntimeError(f"friction reference: more than {modes.friction.max_events} switches in the step at t0 = {t0}")


def _solve_ivp():
    from .reference import scipy_solve_ivp

    return scipy_solve_ivp()


def friction_reference_trajectories(
    env, y0s, inputs, dt: float, fractions, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """As `dense_reference_trajectories`, through the stick-slip switches of the env's friction.

    One `friction_reference_step` per initial state and env step (the input held over the
    step, the field read at the episode's time `k dt + s`). Returns the states after each
    env step `(B, T, n)` and at `fractions` of each step `(B, T, len(fractions), n)`, from
    the segment covering each time.
    """
    import jax

    y0s = np.asarray(y0s, dtype=np.float64)
    inputs = np.asarray(inputs, dtype=np.float64)
    fractions = np.asarray(fractions, dtype=np.float64)
    states = np.empty((len(y0s), len(inputs), y0s.shape[1]))
    inside = np.empty((len(y0s), len(inputs), len(fractions), y0s.shape[1]))
    with jax.enable_x64(True):
        modes = friction_modes(env)
        for b, y in enumerate(y0s):
            for k, u in enumerate(inputs):
                step = friction_reference_step(
                    modes, y, u, dt, np.float64(k) * np.float64(dt), method=method, rtol=rtol, atol=atol,
                    dense_output=len(fractions) > 0,
                )
                for j, time in enumerate(fractions * dt):
                    segment = next(s for s in step.segments if s.t[0] <= time <= s.t[-1])
                    inside[b, k, j] = segment.sol(time)
                y = states[b, k] = step.y
    return states, inside


def friction_reference_gradient(
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
    import jax
    import jax.numpy as jnp
    from jax.flatten_util import ravel_pytree

    from ..gradients import selection_spec

    inputs = np.asarray(inputs, dtype=np.float64)
    with jax.enable_x64(True):
        params, static = eqx.partition(env, selection_spec(env, where))
        flat, unravel = ravel_pytree(jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64), params))
        flat = np.asarray(flat)
        dt = float(env.dt)

        def loss(x) -> float:
            perturbed = eqx.combine(unravel(jnp.asarray(x)), static)
            y0s = np.asarray(y0)[None]
            states, _ = friction_reference_trajectories(perturbed, y0s, inputs, dt, [], rtol=rtol, atol=rtol)
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
    "FrictionStep", "friction_modes", "friction_reference_gradient", "friction_reference_step",
    "friction_reference_trajectories",
]
