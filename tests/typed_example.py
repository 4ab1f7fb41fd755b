"""A script typed as a user writes one against the public API; the type check covers it
(`tests/test_type_check.py`), so that a constructor a type checker cannot read is caught."""

import diffrax
import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp

import lerax_like as ll
from lerax_like import CartPole, CartPoleDynamics


def build() -> list[ll.AbstractEnv]:
    """Every way of passing a parameter: flat, by dynamics, by integrator, by add-on."""
    return [
        CartPole(),
        CartPole(pole_mass=0.2, gravity=3.7, dt=0.01, solver="rk4", substeps=2),
        CartPole(dynamics=CartPoleDynamics(pole_mass=0.2), x_threshold=float("inf"), restitution=0.5, track_limit=2.0),
        ll.CartPoleContinuous(reward="smooth", action_cost=1e-2, joint_damping=0.1),
        ll.Pendulum(g=9.81, max_speed=8.0, solver=diffrax.Tsit5(), stepsize_controller=diffrax.PIDController(rtol=1e-6, atol=1e-8)),
        ll.DoubleCartPole(task="swing_up", pole_masses=(0.1, 0.2), pole_lengths=jnp.ones(2)),
        ll.NLinkPendulum(masses=[1.0, 1.0, 1.0], integrator=ll.make_integrator("tsit5", max_steps=64)),
        ll.BouncingBall(restitution=0.8, mass=jnp.asarray(2.0)),
        ll.Acrobot(equations="nips"),
    ]


def step_once(env: ll.AbstractEnv) -> float:
    state, observation, _ = env.reset(key=jax.random.key(0))
    action = env.action_space.sample(key=jax.random.key(1))
    state, observation, reward, terminated, truncated, info = env.step(state, action, key=jax.random.key(2))
    del observation, terminated, truncated, info
    return float(reward)


def heavier(env: CartPole) -> CartPole:
    return eqx.tree_at(lambda e: e.dynamics.pole_mass, env, jnp.asarray(0.5))


def gymnasium_env() -> gymnasium.Env:
    return gymnasium.make("lerax_like/CartPole-v1", gravity=3.7)


if __name__ == "__main__":
    print([step_once(env) for env in build()[:2]], heavier(CartPole()).dynamics.pole_mass, gymnasium_env())
