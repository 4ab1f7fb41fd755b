"""The driven pendulum against SciPy, the drive read at the episode's time.

Each env step integrates over `dt` with the vector field at `t0 + s`, `t0 = steps * dt`:
over many steps the env must follow one SciPy solve of the whole episode. A step that
restarted the drive's clock at 0 (the package before issue 31) is 0.1 to 1 rad off here.
"""

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import lerax_like as ll

from .scene import DrivenPendulum


def _scipy_episode(env, y0, t0, torques, dt):
    """One DOP853 solve at rtol 1e-13 from episode time `t0`, the torque piecewise constant."""
    p = env.dynamics
    omega0, damping, amplitude, frequency = (float(x) for x in (p.natural_frequency, p.damping, p.drive_amplitude, p.drive_frequency))
    states, y = [], np.asarray(y0, dtype=np.float64)
    for k, torque in enumerate(torques):
        start = t0 + k * dt

        def field(t, y, torque=torque):
            return [y[1], -(omega0**2) * np.sin(y[0]) - damping * y[1] + amplitude * np.cos(frequency * t) + torque]

        y = solve_ivp(field, (start, start + dt), y, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
        states.append(y)
    return np.stack(states)


# One compilation for every case: the start, the step count and the actions are arguments.
_rollout = eqx.filter_jit(ll.rollout)


@pytest.mark.parametrize("start_step", [0, 1000], ids=["from_reset", "mid_episode"])
def test_a_driven_pendulum_follows_scipy_with_episode_time(start_step):
    integrator = ll.make_integrator("dopri8", diffrax.PIDController(rtol=1e-12, atol=1e-12), max_steps=10_000)
    env = ll.make(DrivenPendulum, integrator=integrator, drive_amplitude=1.5)  # Baker and Gollub's chaotic drive
    steps, dt = 200, float(env.dt)  # 10 s: more than one period of the drive (3 pi s)
    actions = np.sin(0.3 * np.arange(steps))[:, None]
    y0 = np.array([0.2, -0.1])
    state = ll.EnvState(y=jnp.asarray(y0), steps=jnp.asarray(start_step))
    ys, info = _rollout(env, state, jnp.asarray(actions))
    assert np.all(np.asarray(info["solver_ok"]))
    torques = float(env.torque_mag) * actions[:, 0]
    reference = _scipy_episode(env, y0, start_step * dt, torques, dt)
    np.testing.assert_allclose(np.asarray(ys), reference, rtol=0, atol=1e-9)
    # The clock matters here: the same solve with the drive restarted at 0 each step is far off.
    restarted = np.concatenate([_scipy_episode(env, y, 0.0, [torque], dt) for y, torque in zip(
        np.concatenate([y0[None], np.asarray(ys)[:-1]]), torques)])
    assert np.max(np.abs(restarted - reference)) > 1e-3


@pytest.mark.slow
def test_the_study_reads_the_drive_at_episode_time():
    # The study's SciPy reference and the solver's dense output must read the drive at the
    # episode's time too: with either clock restarted per step, Dopri8 at rtol 1e-12 would be
    # 1e-3 off its reference instead of at the reference's floor.
    from lerax_like.analysis import SolverSweep, StudyConfig, run_study

    config = StudyConfig(
        scene="DrivenPendulum", sweeps=(SolverSweep("dopri8", tolerances=((1e-12, 1e-14),)),),
        schedules=("recorded",), horizon=40, batch=2, repeats=1,
    )
    (row,) = run_study(config, progress=False).rows
    assert row["solver_ok"]
    assert row["max_error"] < 1e-9 and row["linf_error"] < 1e-9, row
