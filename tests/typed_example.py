"""A script typed as a user writes one against the public API, a scene of the user's own included
(written as docs/new_scene.md says); the type check covers it (`tests/test_type_check.py`), so that
a constructor a type checker cannot read is caught."""

from typing import ClassVar, final

import diffrax
import equinox as eqx
import gymnasium
import jax
import jax.numpy as jnp

import lerax_like as ll
from lerax_like import CartPole, CartPoleDynamics


@final
class SpringDynamics(ll.AbstractDynamics):
    """A mass on a spring: `y = [x, x_dot]`, a force `u[0]` on the mass."""

    velocity_indices: ClassVar[tuple[int, ...]] = (1,)

    mass: jax.Array = eqx.field(default=1.0, converter=ll.POSITIVE)
    stiffness: jax.Array = eqx.field(default=4.0, converter=ll.POSITIVE)

    def vector_field(self, t, y, u):
        del t
        return jnp.stack([y[1], (u[0] - self.stiffness * y[0]) / self.mass])


@final
class Spring(ll.AbstractUnitActionEnv):
    """Hold the mass at rest at the origin with a bounded force."""

    stochastic: ClassVar[bool] = False
    action_size: ClassVar[int] = 1

    dynamics: SpringDynamics = eqx.field(default_factory=SpringDynamics)
    integrator: ll.Integrator = eqx.field(default="rk4", converter=ll.make_integrator)
    force_mag: jax.Array = eqx.field(default=1.0, converter=ll.POSITIVE)
    dt: jax.Array = eqx.field(default=0.05, converter=ll.POSITIVE)
    max_episode_steps: int | None = 200

    @property
    def initial_bounds(self):
        return -jnp.ones(2, self.dt.dtype), jnp.ones(2, self.dt.dtype)

    def physical_input(self, action):
        return self.force_mag * jnp.clip(action, -1.0, 1.0)

    def reward(self, state, action, next_state, *, key):
        del state, action, key
        return -jnp.sum(next_state.y**2)

    @property
    def worst_reward(self):
        return -jnp.asarray(jnp.inf, self.dt.dtype)


def build() -> list[ll.AbstractEnv]:
    """Every way of passing a parameter: by field, by dynamics, by integrator, by add-on, flat."""
    return [
        CartPole(),
        CartPole(dynamics=CartPoleDynamics(pole_mass=0.2, gravity=3.7), dt=0.01, integrator=ll.make_integrator("rk4", substeps=2)),
        CartPole(CartPoleDynamics(pole_mass=0.2), x_threshold=float("inf"), contacts=(ll.physics.contact.Walls(restitution=0.5, track_limit=2.0),)),
        ll.CartPoleContinuous(reward_kind="smooth", action_cost=1e-2, forces=(ll.JointDamping(joint_damping=0.1),)),
        ll.Pendulum(integrator=diffrax.Tsit5()),
        ll.Pendulum(integrator=ll.make_integrator(diffrax.Tsit5(), diffrax.PIDController(rtol=1e-6, atol=1e-8))),
        ll.DoubleCartPole(task="swing_up", dynamics=ll.CartChainDynamics(pole_masses=(0.1, 0.2), pole_lengths=jnp.ones(2))),
        ll.NLinkPendulum(dynamics=ll.NLinkPendulumDynamics(masses=[1.0, 1.0, 1.0]), integrator=ll.make_integrator("tsit5", max_steps=64)),
        ll.BouncingBall(dynamics=ll.BallDynamics(mass=jnp.asarray(2.0))),
        ll.Acrobot(dynamics=ll.AcrobotDynamics(equations="nips")),
        ll.make("CartPole", pole_mass=0.2, solver="rk4", joint_damping=0.5),
        Spring(dynamics=SpringDynamics(stiffness=9.0), force_mag=2.0),
    ]


def step_once(env: ll.AbstractEnv) -> float:
    state, observation, _ = env.reset(key=jax.random.key(0))
    action = env.action_space.sample(key=jax.random.key(1))
    state, observation, reward, terminated, truncated, info = env.step(state, action, key=jax.random.key(2))
    del observation, terminated, truncated, info
    return float(reward)


def heavier(env: CartPole) -> CartPole:
    return eqx.tree_at(lambda e: e.dynamics.pole_mass, env, jnp.asarray(0.5))


def stiffer(env: Spring) -> jax.Array:
    return env.dynamics.stiffness * 2


def gymnasium_env() -> gymnasium.Env:
    return gymnasium.make("lerax_like/CartPole-v1", gravity=3.7)


if __name__ == "__main__":
    print([step_once(env) for env in build()], heavier(CartPole()).dynamics.pole_mass, gymnasium_env())
