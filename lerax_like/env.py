"""The functional env API: `reset` and `step` on top of smaller, overridable pieces.

An env is an Equinox module, so it is a pytree: its physical parameters are leaves that
`jax.grad` differentiates and `eqx.filter_vmap` batches, and every method is pure.
"""

import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

from ._types import Array, BoolScalar, Float, Input, IntScalar, Key, Scalar, State
from .integrate import Integrator
from .physics import AbstractDynamics
from .spaces import AbstractSpace


def _part_keys(key: Key, count: int, stochastic: bool) -> tuple[Key | None, ...]:
    """Keys for the `count` parts of a `reset` or a `step`, the one that draws the start last.

    A stochastic env's parts each get their own key, `jr.fold_in(key, i)`: unlike
    `jr.split(key, count)`, which hashes all `count` counters in one op, each `fold_in` is
    its own small op, so XLA drops the keys a part never uses. A deterministic env's parts
    get `None`, and the start draw gets `key` itself: key work dominates a vmapped env
    step, and deriving a key costs a hash, as much as a draw.
    """
    if stochastic:
        return tuple(jr.fold_in(key, i) for i in range(count))
    return (None,) * (count - 1) + (key,)  # `(None,) * count` when `key` is None


class EnvState(eqx.Module):
    """The state of an env: the continuous state `y` and the env steps taken in this episode.

    Time within the episode is `steps * dt`, never an accumulated sum.
    """

    y: State
    steps: IntScalar


class AbstractEnv(eqx.Module):
    """A continuous-time control env: physics (`dynamics`), an `integrator` and a task.

    Scenes provide `initial`, `physical_input`, `observation`, `reward`, `terminal` and
    the two spaces; `transition`, `truncate`, `reset` and `step` are built from them.

    `stochastic` says whether `transition`, `observation`, `reward` or `terminal` draw
    random numbers (`initial` always does). True, the safe default, gives each its own
    key. A scene that declares False, as every scene here does, has them called with
    `key=None` (one that draws anyway fails at once), and its `reset` and `step` hand
    their whole key to `initial`: key work dominates a vmapped step.
    """

    stochastic: ClassVar[bool] = True

    dynamics: eqx.AbstractVar[AbstractDynamics]
    integrator: eqx.AbstractVar[Integrator]
    dt: eqx.AbstractVar[Scalar]
    max_episode_steps: eqx.AbstractVar[int | None]

    @property
    @abc.abstractmethod
    def action_space(self) -> AbstractSpace: ...

    @property
    @abc.abstractmethod
    def observation_space(self) -> AbstractSpace: ...

    @abc.abstractmethod
    def initial(self, *, key: Key) -> EnvState:
        """A random initial state.

        The scenes here draw it with `lerax_like._random.uniform`: 16 random bits per
        coordinate, one hash for four, since key work dominates a vmapped step.
        """

    @abc.abstractmethod
    def physical_input(self, action: Array) -> Input:
        """The physical input `u` (forces, torques) that `action` applies to the dynamics."""

    @abc.abstractmethod
    def observation(self, state: EnvState, *, key: Key | None) -> Float[Array, "..."]:
        """What the agent sees of `state`."""

    @abc.abstractmethod
    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        """The reward of the transition `state --action--> next_state`."""

    @abc.abstractmethod
    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        """Whether `state` ends the episode (the task's own end, not a time limit)."""

    def project(self, y: State) -> State:
        """Map a state onto the scene's admissible states (speed limits, walls, wrapping).

        Identity unless a scene overrides it. It must be idempotent. `transition` hands
        it to the integrator, which applies it after every step whatever the solver, and
        inside the step with `SemiImplicitEuler` (between the velocity and the position
        updates): that is how Gymnasium's clipped envs are reproduced without a
        special case per env.
        """
        return y

    def transition(
        self, state: EnvState, action: Array, *, key: Key | None
    ) -> tuple[EnvState, dict[str, Array]]:
        """Integrate the dynamics over `[0, dt]` with the action's input held constant.

        The end state is projected by `project`; with `SemiImplicitEuler`, the state
        after the velocity update is projected too (see `Integrator.integrate`).

        The info holds `solver_ok` and `solver_steps`. A failed solve (non-finite state,
        exhausted step budget) keeps the pre-step state, so that nothing non-finite
        leaves the env; `step` ends the episode on it.
        """
        del key
        u = self.physical_input(action)
        y, info = self.integrator.integrate(
            self.dynamics.vector_field,
            state.y,
            u,
            self.dt,
            projection=self.project,
            velocity_indices=self.dynamics.velocity_indices,
        )
        y = jnp.where(info["solver_ok"], y, state.y)
        return EnvState(y=y, steps=state.steps + 1), info

    def truncate(self, state: EnvState) -> BoolScalar:
        """Whether the episode's time limit is reached."""
        if self.max_episode_steps is None:
            return jnp.asarray(False)
        return state.steps >= self.max_episode_steps

    def reset(self, *, key: Key) -> tuple[EnvState, Array, dict[str, Array]]:
        observation_key, initial_key = _part_keys(key, 2, self.stochastic)
        state = self.initial(key=initial_key)
        return state, self.observation(state, key=observation_key), {}

    def step(
        self, state: EnvState, action: Array, *, key: Key
    ) -> tuple[EnvState, Array, Scalar, BoolScalar, BoolScalar, dict[str, Array]]:
        """One env step, with autoreset.

        When the episode ends (terminated or truncated) the returned state and
        observation are those of a fresh episode; the last observation of the ended one
        is `info["final_observation"]`.

        Failures are reported, never silent. `info["solver_ok"]` is False when the solve
        failed (non-finite state, step budget exhausted, step size collapsed, Newton
        diverged) or when a finite state still gave a non-finite observation or reward
        (overflow). Such a step *terminates* the episode, and nothing non-finite is
        returned: the state stays at the pre-step state (see `transition`), a non-finite
        observation is replaced by the pre-step state's and a non-finite reward by 0.

        Terminated rather than truncated: truncation tells an agent to bootstrap from
        `final_observation` as if the episode could have gone on from it, but after a
        failure there is no true next state to bootstrap from (the returned one is the
        pre-step state, a transition that never happened); and in the MDP the env
        actually computes (solver included) a state that overflows is absorbing. A
        terminal with no future reward is also the conservative signal: an agent learns
        to avoid the actions that break the solver rather than to exploit them.
        `info["solver_ok"]` tells this end apart from the task's own.
        """
        transition_key, observation_key, reward_key, terminal_key, reset_key = _part_keys(key, 5, self.stochastic)
        next_state, info = self.transition(state, action, key=transition_key)
        observation = self.observation(next_state, key=observation_key)
        reward = self.reward(state, action, next_state, key=reward_key)
        # The last line of defence: a finite state can overflow in an observation or a
        # reward (a square of 1e200, say).
        observation_ok = jnp.all(jnp.isfinite(observation))
        reward_ok = jnp.isfinite(reward)
        observation = jnp.where(observation_ok, observation, self.observation(state, key=observation_key))
        reward = jnp.where(reward_ok, reward, jnp.zeros_like(reward))
        info = {**info, "solver_ok": info["solver_ok"] & observation_ok & reward_ok}
        terminated = self.terminal(next_state, key=terminal_key) | ~info["solver_ok"]
        truncated = self.truncate(next_state)
        done = terminated | truncated
        reset_state, reset_observation, _ = self.reset(key=reset_key)
        new_state = jax.tree.map(lambda fresh, old: jnp.where(done, fresh, old), reset_state, next_state)
        new_observation = jnp.where(done, reset_observation, observation)
        info = {**info, "final_observation": observation}
        return new_state, new_observation, reward, terminated, truncated, info


def rollout(
    env: AbstractEnv, state: EnvState, actions: Array, *, key: Key
) -> tuple[Float[Array, "T n"], dict[str, Array]]:
    """Apply `actions` (leading axis: time) with `env.transition`, without termination or reset.

    Returns the states after each action (shape `(T, n)`) and the per-step solver info.
    Pure, so `jax.grad` of a loss of the trajectory flows to parameters, actions, `dt`
    and the initial state.
    """
    # A deterministic env's transitions get no key (`None`, an empty pytree to `scan`).
    keys = jr.split(key, actions.shape[0]) if env.stochastic else None

    def body(state, inputs):
        action, step_key = inputs
        next_state, info = env.transition(state, action, key=step_key)
        return next_state, (next_state.y, info)

    _, (ys, infos) = jax.lax.scan(body, state, (actions, keys))
    return ys, infos
