"""SciPy reference solutions through Coulomb stick-slip: each mode solved by `solve_ivp`, each switch an event.

For a scene with a friction add-on (`env.friction`, `lerax_like.physics.friction`), the studies'
reference integrates each env step mode by mode, as `hybrid_reference` does through impacts:
`solve_ivp` (DOP853 by default) in the mode's vector field with the mode's conditions as
terminal `events` (falling through zero), restarted at the first located one in the next mode.
The modes, their fields, their conditions and the rule for the next mode are the package's
(`lerax_like.stick_slip.FrictionModes`); what is independent is the integrator and the event
location. A condition that starts at zero and rises (the switch just taken) is no event for
SciPy (a falling crossing needs a value >= 0 before and <= 0 after).
"""

import numpy as np


def friction_reference_trajectories(
    env, y0s, inputs, dt: float, fractions, *, method: str = "DOP853", rtol: float = 1e-13, atol: float = 1e-13,
) -> tuple[np.ndarray, np.ndarray]:
    """As `dense_reference_trajectories`, through the stick-slip switches of the env's friction.

    One solve per initial state and env step (the input held over the step), restarted at
    every switch. Returns the states after each env step `(B, T, n)` and at `fractions` of
    each step `(B, T, len(fractions), n)`, from the segment covering each time. A slip that
    no friction force makes consistent (Painleve), or more switches than the add-on's
    `max_events`, raises `RuntimeError`.
    """
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from ..stick_slip import FrictionModes
    from .reference import scipy_solve_ivp

    solve_ivp = scipy_solve_ivp()
    y0s = np.asarray(y0s, dtype=np.float64)
    inputs = np.asarray(inputs, dtype=np.float64)
    fractions = np.asarray(fractions, dtype=np.float64)
    states = np.empty((len(y0s), len(inputs), y0s.shape[1]))
    inside = np.empty((len(y0s), len(inputs), len(fractions), y0s.shape[1]))
    friction = env.friction[0]
    with jax.enable_x64(True):
        modes = FrictionModes(physics=env.physics, dynamics=env.dynamics, friction=friction)
        modes = jax.tree.map(lambda leaf: jnp.asarray(leaf, jnp.float64) if eqx.is_inexact_array(leaf) else leaf, modes)
        # Env step k reads the episode's time k dt + t (`FrictionModes.t0`).
        at = lambda t0: eqx.tree_at(lambda m: m.t0, modes, t0)
        field = jax.jit(lambda t0, t, y, u, mode: at(t0).vector_field(t, y, (u, mode)))
        conditions = jax.jit(lambda t0, t, y, u, mode: at(t0).conditions(t, y, (u, mode)))
        settle = jax.jit(lambda t0, t, y, u, mode, ended, which: at(t0).settle(t, y, u, mode, ended, which))
        for b, y in enumerate(y0s):
            for k, u in enumerate(inputs):
                u = jnp.asarray(u)
                t, mode, ended, which, segments = 0.0, (jnp.zeros(()), jnp.ones(())), False, 0, []
                for _ in range(friction.max_events + 1):
                    y, mode, consistent = settle(k * dt, t, jnp.asarray(y), u, mode, jnp.asarray(ended), jnp.asarray(which))
                    if not bool(consistent):
                        raise RuntimeError(f"friction reference: no consistent slip at t = {k * dt + t} (Painleve)")
                    events = []
                    for i in range(4):
                        def event(t, y, i=i, mode=mode):
                            return float(conditions(k * dt, t, y, u, mode)[i])

                        event.terminal, event.direction = True, -1
                        events.append(event)
                    solution = solve_ivp(
                        lambda t, y, mode=mode: np.asarray(field(k * dt, t, y, u, mode)), (t, dt), np.asarray(y),
                        method=method, rtol=rtol, atol=atol, events=events, dense_output=len(fractions) > 0,
                    )
                    if solution.status == -1:
                        raise RuntimeError(f"friction reference solve ({method}) failed at t={t}: {solution.message}")
                    segments.append(solution)
                    hits = [(solution.t_events[i][0], i) for i in range(4) if len(solution.t_events[i])]
                    if not hits:
                        y = solution.y[:, -1]
                        break
                    t, which = min(hits)
                    y, ended = solution.y_events[which][0], True
                else:
                    raise RuntimeError(f"friction reference: more than {friction.max_events} switches in env step {k}")
                for j, time in enumerate(fractions * dt):
                    segment = next(s for s in segments if s.t[0] <= time <= s.t[-1])
                    inside[b, k, j] = segment.sol(time)
                states[b, k] = y
    return states, inside


__all__ = ["friction_reference_trajectories"]
