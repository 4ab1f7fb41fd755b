"""The functional env API: a scene is dynamics + integrator + task, stepped by one pipeline.

An env is an Equinox module, so it is a pytree: its physical parameters are leaves that
`jax.grad` differentiates and `eqx.filter_vmap` batches, and every method is pure.

A scene declares its parts as fields and nothing else: `dynamics` (a physics module),
`integrator` (an `Integrator`, or a preset name or diffrax solver that its converter makes
one), its add-ons and its task's parameters (`eqx.field(converter=POSITIVE)`, `option(...)`).
Its `__init__` is the one Equinox's dataclass writes: `CartPole(integrator="rk4",
dynamics=CartPoleDynamics(pole_mass=0.2))`. Flat keywords, as Gymnasium users pass them
(`pole_mass=0.2, solver="rk4"`), are resolved in one place, `lerax_like.make`.
The step semantics (keys, failure guards, autoreset) live in `advance` and `step`, which
everything else calls: `rollout`, the Gymnasium layer, the studies.
"""

import abc
import functools
from typing import Any, ClassVar, Generic, NamedTuple, TypeVar, cast, overload

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.random as jr

from ._episode import episode_limit, episode_time
from ._fields import AbstractParametrised, concrete, in_precision_of
from ._random import uniform
from ._segments import AbstractModes, integrate_hybrid
from ._types import Array, ArrayLike, BoolScalar, Float, Input, IntScalar, Key, Scalar, ScalarLike, State
from .contact_friction import ContactsWithFriction
from .floor_contact import FloorModes
from .hybrid import Surfaces
from .integrate import Integrator, forward_mode_hint
from .physics import AbstractChainDynamics, AbstractDynamics
from .spaces import AbstractSpace, Box, eager_spaces
from .stick_slip import FrictionModes


def _step_info_shapes(env: "AbstractEnv", state: "EnvState", action) -> dict[str, jax.ShapeDtypeStruct]:
    """The shapes and dtypes of a step's info, traced once per structure of env, state and
    action (a hybrid scene's step takes 0.3 to 0.6 s to trace: every eager `reset` paid it)."""
    dynamic, static = eqx.partition((env, state, action), lambda x: eqx.is_array(x) or isinstance(x, jax.ShapeDtypeStruct))
    leaves, treedef = jax.tree.flatten(dynamic)
    weak = lambda x: x.weak_type if isinstance(x, jax.ShapeDtypeStruct) else jax.typeof(x).weak_type
    structs = tuple(jax.ShapeDtypeStruct(x.shape, x.dtype, weak_type=weak(x)) for x in leaves)
    # (The float dtype in the key: under `jax.enable_x64` the same env traces to float64.)
    key = (static, treedef, structs, jnp.result_type(float))
    try:
        hash(key)
    except TypeError:  # a static part of a user's own that cannot be hashed: traced every time
        return _traced_info_shapes.__wrapped__(*key)
    return _traced_info_shapes(*key)


@functools.lru_cache(maxsize=256)
def _traced_info_shapes(static, treedef, structs, float_dtype) -> dict[str, jax.ShapeDtypeStruct]:
    def info(*leaves):
        env, state, action = eqx.combine(jax.tree.unflatten(treedef, leaves), static)
        return env.advance(state, action, key=jr.key(0))[-1]

    return jax.eval_shape(info, *structs)


class EnvState(eqx.Module):
    """The state of an env: the continuous state `y` and the env steps taken in this episode.

    Time within the episode is `steps * dt` (`episode_time`), never an accumulated sum.
    """

    y: State
    steps: IntScalar


# The type of a step's reset key: a `Key` where the step was given one (`step`), else `Key | None`.
_ResetKey = TypeVar("_ResetKey", bound=Key | None)


class StepKeys(NamedTuple, Generic[_ResetKey]):
    """The keys of one step's parts; `None` for every part but `reset` in a deterministic env."""

    transition: Key | None
    observation: Key | None
    reward: Key | None
    terminal: Key | None
    reset: _ResetKey


class Attempt(NamedTuple):
    """A step as integrated and observed, before `advance`'s failure rule (`AbstractEnv.attempt`)."""

    next_state: EnvState
    observation: Array
    reward: Scalar
    info: dict[str, Array]
    """The solver's info (`solver_ok`: the solve alone) and `action_ok`; `conclude` adds the
    observation's and the reward's finiteness to `solver_ok`."""


@overload
def step_keys(key: Key, stochastic: bool) -> StepKeys[Key]: ...
@overload
def step_keys(key: Key | None, stochastic: bool) -> StepKeys[Key | None]: ...
def step_keys(key: Key | None, stochastic: bool) -> StepKeys[Any]:
    """The keys of a step's parts: the one key derivation of the package.

    A stochastic env's parts each get `jr.fold_in(key, i)`: unlike `jr.split(key, 5)`,
    which hashes all counters in one op, each `fold_in` is its own small op, so XLA drops
    the keys a part never uses. A deterministic env's parts get `None` and the start draw
    gets `key` itself: key work dominates a vmapped env step, and a derived key costs a
    hash, as much as a draw.
    """
    if stochastic:
        if key is None:
            raise ValueError("a stochastic env's step needs a key, got key=None")
        return StepKeys(*(jr.fold_in(key, i) for i in range(5)))
    return StepKeys(None, None, None, None, key)


class AbstractEnv(AbstractParametrised):
    """A continuous-time control env: physics (`dynamics`), an `integrator` and a task.

    A scene provides `physical_input`, `reward`, `initial_bounds`, `worst_reward` and
    `action_space`; `observation` (the state), `observation_space` (unbounded), `terminal`
    (never) and `project` (identity) have defaults that a scene overrides where its task
    differs. It declares:

    - `stochastic`: whether `transition`, `observation`, `reward` or `terminal` draw random
      numbers (`initial` always does). A deterministic scene's parts get `key=None` (one
      that draws anyway fails at once), and its whole key goes to the start draw.
    - `stiff`: whether its dynamics are stiff, so that the studies' SciPy reference uses
      Radau instead of DOP853 (False unless declared).
    - `aliases`: other names its keywords go by (`("reward", "reward_kind")`; Gymnasium's
      names, such as Pendulum's `g`).
    - `addons`: the add-ons it accepts: generalised forces (`JointDamping`, `EndStops`),
      held in a field `forces`, and contacts (`Walls`, `lerax_like.physics.contact`),
      held in a field `contacts` (both empty by default, so that a scene built without
      them carries and computes none of it).

    Whether a scene clips or wraps its state is not declared but read off: it overrides
    `project` (`projects_state`).
    """

    stochastic: eqx.AbstractClassVar[bool]
    stiff: ClassVar[bool] = False
    addons: ClassVar[tuple[type, ...]] = ()
    aliases: ClassVar[tuple[tuple[str, str], ...]] = ()

    dynamics: eqx.AbstractVar[AbstractDynamics]
    integrator: eqx.AbstractVar[Integrator]
    dt: eqx.AbstractVar[Scalar]
    max_episode_steps: eqx.AbstractVar[IntScalar | None]

    def __check_init__(self):
        for contact in getattr(self, "contacts", ()):
            contact.check(self.dynamics)
        friction = getattr(self, "friction", ())
        for addon in friction:
            addon.check(self.dynamics)
        if len(friction) > 1:  # friction beside located contacts is one loop: `lerax_like.contact_friction`
            raise ValueError(f"{type(self).__name__} takes at most one friction add-on, got {len(friction)}")

    def __init_subclass__(cls, **keywords):
        super().__init_subclass__(**keywords)
        eager_spaces(cls)  # NumPy bounds inside a jitted trainer that closes over the env

    # -- what a scene provides ---------------------------------------------------------

    @property
    @abc.abstractmethod
    def action_space(self) -> AbstractSpace: ...

    @property
    def observation_space(self) -> AbstractSpace:
        """Unbounded, of the state's shape, unless a scene declares it (a fully observed scene)."""
        low, _ = self.initial_bounds
        return Box(-jnp.inf, jnp.inf, low.shape)

    @property
    @abc.abstractmethod
    def initial_bounds(self) -> tuple[Float[Array, " n"], Float[Array, " n"]]:
        """`(low, high)`: the start is uniform in `[low, high)` per coordinate (low == high: fixed)."""

    @abc.abstractmethod
    def physical_input(self, action: Array) -> Input:
        """The physical input `u` (forces, torques) that `action` applies to the dynamics."""

    def observation(self, state: EnvState, *, key: Key | None) -> Float[Array, "..."]:
        """What the agent sees of `state`: the state itself, unless a scene declares otherwise."""
        del key
        return state.y

    @abc.abstractmethod
    def reward(self, state: EnvState, action: Array, next_state: EnvState, *, key: Key | None) -> Scalar:
        """The reward of the transition `state --action--> next_state`."""

    @property
    @abc.abstractmethod
    def worst_reward(self) -> Scalar:
        """A lower bound of the task's rewards for actions in the action space: a failed
        step pays it, so that breaking the solver never pays an agent."""

    def terminal(self, state: EnvState, *, key: Key | None) -> BoolScalar:
        """Whether `state` ends the episode (the task's own end, not a time limit).

        Never, unless a scene declares an end: the episode then ends by its time limit or a
        failed step only.
        """
        del state, key
        return jnp.asarray(False)

    # -- built from the above ----------------------------------------------------------

    @property
    def physics(self) -> AbstractDynamics:
        """What a step integrates: `dynamics`, with the scene's add-on forces if it has any."""
        forces = getattr(self, "forces", ())
        if not forces:
            return self.dynamics
        from .physics.forces import ForcedDynamics

        dynamics = self.dynamics
        if not isinstance(dynamics, AbstractChainDynamics):  # the add-ons' `check` refused it at construction
            raise TypeError(f"{type(self).__name__}'s forces act on a cart or a chain, not on {type(dynamics).__name__}")
        return ForcedDynamics(dynamics=dynamics, forces=forces)

    @classmethod
    def projects_state(cls) -> bool:
        """Whether the scene clips or wraps its state after each step (overrides `project`)."""
        return cls.project is not AbstractEnv.project

    def initial(self, *, key: Key) -> EnvState:
        """A start uniform within `initial_bounds`.

        Drawn with `lerax_like._random.uniform`: 16 random bits per coordinate, one hash
        for four, since key work dominates a vmapped step.
        """
        low, high = self.initial_bounds
        y = uniform(key, low.shape, self.dt.dtype, low, high)
        return EnvState(y=y, steps=jnp.zeros((), dtype=int))

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
        """Integrate the physics over one step under the action's physical input (`evolve`)."""
        del key
        return self.evolve(state, self.physical_input(action))

    def evolve(self, state: EnvState, u: Input) -> tuple[EnvState, dict[str, Array]]:
        """Integrate the physics over one step with the physical input `u` held constant.

        The field reads the episode's time, `steps * dt + s` at `s` into the step; the solve
        runs over `[0, dt]` (`EpisodeTime`): autonomous results do not change, bit for bit.

        The end state is projected by `project` (if the scene overrides it); with
        `SemiImplicitEuler`, the state after the velocity update is projected too.

        A hybrid scene (`modes`: contacts, Coulomb friction, both, a disk's floor) is
        integrated by the one hybrid loop (`lerax_like._segments.integrate_hybrid`), segment
        by segment, its impacts and stick-slip switches located as events; its info also
        holds, for each kind of event, how many (`impacts`, `switches`) and the time of the
        first (`first_impact_time`, `first_switch_time`), and the modes' checks
        (`friction_consistent`).

        The info holds `solver_ok`, `solver_steps` and `solver_rejected_steps`. A failed
        solve (non-finite state, exhausted step budget) keeps the pre-step state, so that
        nothing non-finite leaves the env. The studies call this directly, with inputs an
        action cannot express (a zero force on `CartPole`).
        """
        physics, u = self.physics, in_precision_of(state.y, u)
        t0 = episode_time(state.steps, self.dt)
        projection = self.project if self.projects_state() else None
        modes = self.modes(t0)
        with forward_mode_hint(self.integrator.adjoint):
            if modes is None:
                y, info = self.integrator.integrate(
                    physics.vector_field, state.y, u, self.dt, projection=projection,
                    velocity_indices=physics.velocity_indices, t0=t0,
                )
            else:
                y, info = integrate_hybrid(
                    self.integrator, modes, state.y, u, self.dt, velocity_indices=physics.velocity_indices,
                    projection=projection,
                )
        y = jnp.where(info["solver_ok"], y, state.y)
        return EnvState(y=y, steps=state.steps + 1), info

    def modes(self, t0: ScalarLike = 0.0) -> AbstractModes | None:
        """The scene as a hybrid system (`lerax_like._segments.AbstractModes`), its physics read
        at the episode's time `t0` plus the step's; None for a smooth scene.

        Contacts (a field `contacts`, `lerax_like.physics.contact`): `Surfaces`, impacts located.
        Coulomb friction (a field `friction`, `lerax_like.physics.friction`): `FrictionModes`,
        stick and slip. Both: `ContactsWithFriction`. A disk's floor (a field `floor`,
        `lerax_like.physics.rolling_disk.DiskFloor`): `FloorModes`.
        """
        contacts, friction, floor = getattr(self, "contacts", ()), getattr(self, "friction", ()), getattr(self, "floor", None)
        t0 = jnp.asarray(t0, self.dt.dtype)
        if floor is not None:
            return FloorModes(dynamics=cast(Any, self.dynamics), floor=floor, t0=t0)
        surfaces = Surfaces(physics=self.physics, dynamics=self.dynamics, contacts=tuple(contacts), dt=self.dt, t0=t0)
        if friction:
            stick_slip = FrictionModes(physics=self.physics, dynamics=self.dynamics, friction=friction[0], t0=t0)
            return ContactsWithFriction(surfaces=surfaces, friction=stick_slip) if contacts else stick_slip
        return surfaces if contacts else None

    def check_state(self, state: EnvState) -> None:
        """Refuse, by name, a state whose shape does not fit the scene (at trace time)."""
        if not isinstance(state, EnvState):
            raise TypeError(f"state must be an EnvState (from reset or step), got {type(state).__name__}")
        # The shape of a start: traced, never run (a scene may override `initial`).
        expected = jax.eval_shape(lambda key: self.initial(key=key).y, jr.key(0)).shape
        if jnp.shape(state.y) != expected:
            raise ValueError(
                f"state.y must have shape {expected} (the state of {type(self).__name__}), "
                f"got shape {jnp.shape(state.y)}"
            )

    def __hash__(self) -> int:
        # `jax.jit(env.step)` hashes the bound method, hence `env`, whose array leaves are
        # unhashable; JAX's own message (`unhashable type: ArrayImpl`) does not say why.
        try:
            return eqx.Module.__hash__(self)
        except TypeError as error:
            raise TypeError(
                f"a {type(self).__name__} holds arrays (its parameters) and cannot be hashed, so "
                "jax.jit(env.step) and static arguments fail: use eqx.filter_jit(env.step), or pass "
                "env as an argument of a function under eqx.filter_jit"
            ) from error

    def truncate(self, state: EnvState) -> BoolScalar:
        """Whether the episode's time limit is reached."""
        if self.max_episode_steps is None:
            return jnp.asarray(False)
        return state.steps >= jnp.asarray(self.max_episode_steps, state.steps.dtype)

    def reset(self, *, key: Key) -> tuple[EnvState, Array, dict[str, Array]]:
        """A fresh episode: state, observation, and an info with `step`'s keys and dtypes (so
        that `lax.scan`/`lax.select` mix the two): a step that integrated nothing and failed
        at nothing, every `*_ok` flag True, every count zero, `final_observation` the start's."""
        state, observation = self._start(key)
        action = jax.eval_shape(lambda: self.action_space.sample(key=jr.key(0)))
        shapes = _step_info_shapes(self, state, action)
        info = {name: jnp.full(shape.shape, name.endswith("_ok"), shape.dtype) for name, shape in shapes.items()}
        return state, observation, {**info, "final_observation": observation}

    def _start(self, key: Key) -> tuple[EnvState, Array]:
        keys = step_keys(key, self.stochastic)
        state = self.initial(key=keys.reset)
        return state, self.observation(state, key=keys.observation)

    def advance(
        self, state: EnvState, action: ArrayLike, *, key: Key | None
    ) -> tuple[EnvState, Array, Scalar, BoolScalar, dict[str, Array]]:
        """One step without time limit or reset: the step semantics, defined once.

        Returns the next state, its observation, the reward, whether the episode terminated,
        and the info. `step`, `rollout`, the Gymnasium layer and the studies all step through
        here (the layer through its two halves, `attempt` and `conclude`).

        Failures are reported, never silent: `info["solver_ok"]` is False when the solve
        failed (non-finite state, step budget exhausted, step size collapsed, Newton
        diverged) or when a finite state still gave a non-finite observation or reward
        (an overflow, or a float64 state beyond float32's range). Such a step
        *terminates* the episode and returns nothing non-finite: the state stays at the
        pre-step state (see `transition`), the observation is the pre-step state's, and
        the reward is `worst_reward`, so that breaking the solver never pays an agent.

        Terminated rather than truncated: truncation tells an agent to bootstrap from the
        last observation as if the episode could have gone on, but after a failure there
        is no true next state; in the MDP the env actually computes (solver included) a
        state that overflows is absorbing. `info["solver_ok"]` tells this end apart from
        the task's own.

        Bad input: an `action` whose shape or dtype does not fit `action_space` (see
        `AbstractSpace.check`), or a `state.y` of the wrong shape, is refused with a
        `TypeError`/`ValueError` that names it, when the step is traced. An action of
        fitting shape that cannot be applied (a discrete action out of range, a
        non-finite continuous one) is refused with a `ValueError` when it is concrete
        (an eager call); when it is traced (under `jit`, `vmap`, `scan`) the step is
        reported in `info["action_ok"]` and fails as above (pre-step state, worst reward,
        terminated), never silently applied as another action. This costs no runtime
        check that could stop a hot loop, so there is no switch to turn it off.
        """
        keys = step_keys(key, self.stochastic)
        trial = self.attempt(state, action, key=key)
        return self.conclude(state, trial, self.observation(state, key=keys.observation), key=key)

    def attempt(self, state: EnvState, action: ArrayLike, *, key: Key | None) -> "Attempt":
        """The first half of `advance`: the step as integrated and observed, with the solve's
        and the action's checks (`info["solver_ok"]`, `info["action_ok"]`), before the
        failure rule (`conclude`).

        A caller that holds the pre-step observation already (a batched front end carries the
        last one it returned) passes it to `conclude` instead of observing `state` again; one
        that returns the observation in another dtype casts `attempt.observation` before
        `conclude`, which checks what is returned.
        """
        action = self.action_space.check(action, "action")
        self.check_state(state)
        action_ok = self.action_space.admissible(action)
        ok = concrete(action_ok)
        if ok is not None and not bool(ok):
            space, shown = self.action_space, concrete(action)
            action_text = action if shown is None else shown.tolist()
            raise ValueError(f"action {action_text} is not admissible in {space}: it must be {space.rule}")
        keys, action = step_keys(key, self.stochastic), in_precision_of(state.y, action)
        next_state, info = self.transition(state, action, key=keys.transition)
        observation = self.observation(next_state, key=keys.observation)
        reward = self.reward(state, action, next_state, key=keys.reward)
        return Attempt(next_state, observation, reward, {**info, "action_ok": action_ok})

    def conclude(
        self, state: EnvState, attempt: "Attempt", previous_observation: Array, *, key: Key | None
    ) -> tuple[EnvState, Array, Scalar, BoolScalar, dict[str, Array]]:
        """The second half of `advance`, its failure rule: an attempt from `state` that failed
        (the solve, a non-finite observation or reward: `info["solver_ok"]` False; or
        `action_ok` False) keeps `state`, returns `previous_observation` (the observation of
        `state`), pays `worst_reward` and terminates."""
        keys = step_keys(key, self.stochastic)
        finite = jnp.all(jnp.isfinite(attempt.observation)) & jnp.isfinite(attempt.reward)
        info = {**attempt.info, "solver_ok": attempt.info["solver_ok"] & finite}
        applied = info["solver_ok"] & info["action_ok"]
        next_state = EnvState(y=jnp.where(applied, attempt.next_state.y, state.y), steps=attempt.next_state.steps)
        observation = jnp.where(applied, attempt.observation, previous_observation)
        reward = jnp.where(applied, attempt.reward, jnp.asarray(self.worst_reward, attempt.reward.dtype))
        terminated = self.terminal(next_state, key=keys.terminal) | ~applied
        return next_state, observation, reward, terminated, info

    def step(
        self, state: EnvState, action: Array, *, key: Key
    ) -> tuple[EnvState, Array, Scalar, BoolScalar, BoolScalar, dict[str, Array]]:
        """One env step (`advance`), with time limit and autoreset.

        When the episode ends (terminated or truncated) the returned state and
        observation are those of a fresh episode; the last observation of the ended one
        is `info["final_observation"]`. See `advance` for the failure semantics.
        """
        keys = step_keys(key, self.stochastic)
        next_state, observation, reward, terminated, info = self.advance(state, action, key=key)
        truncated = self.truncate(next_state)
        done = terminated | truncated
        reset_state, reset_observation = self._start(keys.reset)
        new_state = jax.tree.map(lambda fresh, old: jnp.where(done, fresh, old), reset_state, next_state)
        new_observation = jnp.where(done, reset_observation, observation)
        # Strong dtypes (a solver's step count is weak-typed), as `reset`'s info has.
        info = {name: jnp.asarray(value, dtype=value.dtype) for name, value in info.items()}
        return new_state, new_observation, reward, terminated, truncated, {**info, "final_observation": observation}


def rollout(
    env: AbstractEnv, state: EnvState, actions: Array, *, key: Key | None = None, checkpoint: bool = True
) -> tuple[Float[Array, "T n"], dict[str, Array]]:
    """Apply `actions` (leading axis: time) with `env.advance`, without time limit or reset.

    Returns the states after each action (shape `(T, n)`) and the per-step info (the
    rewards under `"reward"`, whether each step terminated under `"terminated"`). A failed
    step keeps its pre-step state, as in `step`. Pure, so `jax.grad` of a loss of the
    trajectory flows to parameters, actions, `dt` and the initial state.

    `checkpoint` (default True): reverse mode keeps the states between env steps and recomputes
    each step on the way back (`jax.checkpoint`); values and gradients are the same. Storing every
    step's solver internals instead (`False`) took 75 GB for 1024 `BouncingBall`s x 100 steps.
    """
    # A deterministic env's steps get no key (`None`, an empty pytree to `scan`).
    keys = None
    if env.stochastic:
        if key is None:
            raise ValueError(f"{type(env).__name__} is stochastic: rollout needs a key")
        keys = jr.split(key, actions.shape[0])

    def body(state, inputs):
        action, step_key = inputs
        next_state, _, reward, terminated, info = env.advance(state, action, key=step_key)
        return next_state, (next_state.y, {**info, "reward": reward, "terminated": terminated})

    if checkpoint:  # no CSE barrier: inside `scan` none is needed (JAX's advice), and it costs
        body = jax.checkpoint(body, prevent_cse=False)
    # Under jax.jacfwd, JAX refuses the adjoint's custom_vjp when it batches the scan's body.
    with forward_mode_hint(env.integrator.adjoint):
        _, (ys, infos) = jax.lax.scan(body, state, (actions, keys))
    return ys, infos


__all__ = [
    "AbstractEnv", "Attempt", "EnvState", "StepKeys", "episode_limit", "episode_time", "rollout", "step_keys",
]
