"""The XLA floor of a vector step: a minimal hand-written JAX step of each registered id.

Gymnasium's equations for each env, written with `jax.numpy` on the batch (shape `(N, n)`
state, as the vector env holds it), with Gymnasium's constants inlined, no autoreset,
no failure checks, no keys. One jitted call per step takes the state (left on the device)
and the actions (from NumPy) and returns the next state, the float32 observation, the
reward and the termination flag; the last three are fetched with `np.asarray`. That is
the least any JAX vector env of the same physics must do per step, so a vector env's
speed over this floor's is the share of its step spent on anything but the physics.
"""

import math

import jax
import jax.numpy as jnp
import numpy as np


def _cartpole(y, action):
    gravity, masscart, masspole, length, force_mag, tau = 9.8, 1.0, 0.1, 0.5, 10.0, 0.02
    total_mass, polemass_length = masspole + masscart, masspole * length
    x, x_dot, theta, theta_dot = y[:, 0], y[:, 1], y[:, 2], y[:, 3]
    force = jnp.where(action == 1, force_mag, -force_mag)
    costheta, sintheta = jnp.cos(theta), jnp.sin(theta)
    temp = (force + polemass_length * theta_dot**2 * sintheta) / total_mass
    thetaacc = (gravity * sintheta - costheta * temp) / (length * (4.0 / 3.0 - masspole * costheta**2 / total_mass))
    xacc = temp - polemass_length * thetaacc * costheta / total_mass
    y = jnp.stack([x + tau * x_dot, x_dot + tau * xacc, theta + tau * theta_dot, theta_dot + tau * thetaacc], axis=1)
    threshold = 12 * 2 * math.pi / 360
    terminated = (y[:, 0] < -2.4) | (y[:, 0] > 2.4) | (y[:, 2] < -threshold) | (y[:, 2] > threshold)
    return y, y, jnp.ones_like(y[:, 0]), terminated


def _pendulum(y, action):
    max_speed, max_torque, dt, g, m, length = 8.0, 2.0, 0.05, 10.0, 1.0, 1.0
    th, thdot = y[:, 0], y[:, 1]
    u = jnp.clip(action[:, 0], -max_torque, max_torque)
    normalized = ((th + math.pi) % (2 * math.pi)) - math.pi
    costs = normalized**2 + 0.1 * thdot**2 + 0.001 * u**2
    newthdot = thdot + (3 * g / (2 * length) * jnp.sin(th) + 3.0 / (m * length**2) * u) * dt
    newthdot = jnp.clip(newthdot, -max_speed, max_speed)
    newth = th + newthdot * dt
    observation = jnp.stack([jnp.cos(newth), jnp.sin(newth), newthdot], axis=1)
    return jnp.stack([newth, newthdot], axis=1), observation, -costs, jnp.zeros_like(th, dtype=bool)


def _acrobot_dsdt(s, torque):
    m1 = m2 = 1.0
    l1, lc1, lc2, i1, i2, g = 1.0, 0.5, 0.5, 1.0, 1.0, 9.8
    theta1, theta2, dtheta1, dtheta2 = s[:, 0], s[:, 1], s[:, 2], s[:, 3]
    d1 = m1 * lc1**2 + m2 * (l1**2 + lc2**2 + 2 * l1 * lc2 * jnp.cos(theta2)) + i1 + i2
    d2 = m2 * (lc2**2 + l1 * lc2 * jnp.cos(theta2)) + i2
    phi2 = m2 * lc2 * g * jnp.cos(theta1 + theta2 - math.pi / 2.0)
    phi1 = (
        -m2 * l1 * lc2 * dtheta2**2 * jnp.sin(theta2)
        - 2 * m2 * l1 * lc2 * dtheta2 * dtheta1 * jnp.sin(theta2)
        + (m1 * lc1 + m2 * l1) * g * jnp.cos(theta1 - math.pi / 2)
        + phi2
    )
    ddtheta2 = (torque + d2 / d1 * phi1 - m2 * l1 * lc2 * dtheta1**2 * jnp.sin(theta2) - phi2) / (
        m2 * lc2**2 + i2 - d2**2 / d1
    )
    ddtheta1 = -(d2 * ddtheta2 + phi1) / d1
    return jnp.stack([dtheta1, dtheta2, ddtheta1, ddtheta2], axis=1)


def _wrap(x, low, high):
    return low + jnp.mod(x - low, high - low)


def _acrobot(y, action):
    dt = 0.2
    torque = (action.astype(y.dtype) - 1.0)[:, None][:, 0]
    k1 = _acrobot_dsdt(y, torque)
    k2 = _acrobot_dsdt(y + dt / 2 * k1, torque)
    k3 = _acrobot_dsdt(y + dt / 2 * k2, torque)
    k4 = _acrobot_dsdt(y + dt * k3, torque)
    s = y + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    s = jnp.stack(
        [
            _wrap(s[:, 0], -math.pi, math.pi),
            _wrap(s[:, 1], -math.pi, math.pi),
            jnp.clip(s[:, 2], -4 * math.pi, 4 * math.pi),
            jnp.clip(s[:, 3], -9 * math.pi, 9 * math.pi),
        ],
        axis=1,
    )
    terminated = -jnp.cos(s[:, 0]) - jnp.cos(s[:, 1] + s[:, 0]) > 1.0
    observation = jnp.stack(
        [jnp.cos(s[:, 0]), jnp.sin(s[:, 0]), jnp.cos(s[:, 1]), jnp.sin(s[:, 1]), s[:, 2], s[:, 3]], axis=1
    )
    return s, observation, jnp.where(terminated, 0.0, -1.0).astype(y.dtype), terminated


def _mountain_car_move(y, acceleration):
    position, velocity = y[:, 0], y[:, 1]
    velocity = jnp.clip(velocity + acceleration + jnp.cos(3 * position) * (-0.0025), -0.07, 0.07)
    position = jnp.clip(position + velocity, -1.2, 0.6)
    velocity = jnp.where((position == -1.2) & (velocity < 0), 0.0, velocity)
    return jnp.stack([position, velocity], axis=1)


def _mountain_car(y, action):
    y = _mountain_car_move(y, (action.astype(y.dtype) - 1) * 0.001)
    terminated = (y[:, 0] >= 0.5) & (y[:, 1] >= 0.0)
    return y, y, -jnp.ones_like(y[:, 0]), terminated


def _mountain_car_continuous(y, action):
    force = jnp.clip(action[:, 0], -1.0, 1.0)
    y = _mountain_car_move(y, force * 0.0015)
    terminated = (y[:, 0] >= 0.45) & (y[:, 1] >= 0.0)
    reward = jnp.where(terminated, 100.0, 0.0) - action[:, 0] ** 2 * 0.1
    return y, y, reward, terminated


STEPS = {
    "CartPole-v1": _cartpole,
    "Pendulum-v1": _pendulum,
    "Acrobot-v1": _acrobot,
    "MountainCar-v0": _mountain_car,
    "MountainCarContinuous-v0": _mountain_car_continuous,
}
"""Gymnasium's name -> the hand-written batched step `(y, action) -> (y, observation, reward, terminated)`."""


class FloorVectorEnv:
    """`step(actions)` of the hand-written step at `dtype`, with what any vector env must
    fetch: the observation, the reward and the flag as NumPy arrays; the state stays on the device."""

    def __init__(self, name: str, initial_state: np.ndarray, dtype: str = "float64"):
        self.dtype = np.dtype(dtype)
        self._x64 = self.dtype == np.float64
        physics = STEPS[name]

        def step(y, action):
            y, observation, reward, terminated = physics(y, action)
            return y, observation.astype(jnp.float32), reward.astype(y.dtype), terminated

        self._step = jax.jit(step)
        with jax.enable_x64(self._x64):
            self._y = jnp.asarray(initial_state, dtype=self.dtype)

    def step(self, actions):
        with jax.enable_x64(self._x64):
            if np.asarray(actions).dtype.kind == "f":
                actions = np.asarray(actions, dtype=self.dtype)
            self._y, observation, reward, terminated = self._step(self._y, actions)
        return np.asarray(observation), np.asarray(reward), np.asarray(terminated)

    def close(self) -> None:
        pass


__all__ = ["FloorVectorEnv", "STEPS"]
