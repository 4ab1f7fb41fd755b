"""The one hybrid loop (`lerax_like._segments.integrate_hybrid`) on a system whose answer is known exactly.

Two clocks' alarms, due at `times`, on a state `[clock, rang_0, rang_1]` that runs at unit
speed: each alarm is a guard `time - clock`, and its reset records the clock in `rang_i`.
Euler's steps and its linear interpolant are exact for this flow, so whatever the step, the
recorded times must be the due times to a few ulps, in the order they fall due.
"""

from typing import ClassVar

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import optimistix
import pytest

import lerax_like as ll
from lerax_like._segments import AbstractModes, Settled, integrate_hybrid


class Alarms(AbstractModes):
    kinds: ClassVar[tuple[str, ...]] = ("alarm",)
    checks: ClassVar[tuple[str, ...]] = ("at_most_two",)
    times: jax.Array

    @property
    def max_events(self) -> int:
        return 2

    def initial_mode(self, y):
        return jnp.zeros(2, bool)  # which alarms have rung

    def vector_field(self, t, y, args):
        return jnp.zeros_like(y).at[0].set(1.0)

    def guards(self, t, y, args):
        _, rang = args
        return jnp.where(rang, 1.0, self.times - y[0])

    def settle(self, t, y, u, mode, fired):
        y = jnp.where(jnp.concatenate([jnp.zeros(1, bool), fired]), y[0], y)
        return Settled(y, mode | fired, (jnp.sum(fired, dtype=int),), {"at_most_two": jnp.sum(mode | fired) <= 2})


@pytest.mark.parametrize("times", [(0.75, 0.5), (0.5, 0.75), (0.25, 0.25 + 2**-20)])
def test_two_guards_crossing_within_one_fixed_step_are_taken_in_time_order(times):
    """One Euler step over the whole env step: both alarms fall due inside it. The loop locates
    the earlier first whatever their order among the guards, then the later one."""
    with jax.enable_x64(True):
        integrator = ll.Integrator(diffrax.Euler())
        y0 = jnp.zeros(3)
        y, info = jax.jit(lambda y0: integrate_hybrid(integrator, Alarms(times=jnp.asarray(times)), y0, None, 1.0))(y0)
        assert bool(info["solver_ok"]) and bool(info["at_most_two"])
        assert int(info["alarms"]) == 2
        np.testing.assert_allclose(np.asarray(y), [1.0, *times], rtol=0, atol=1e-14)
        np.testing.assert_allclose(float(info["first_alarm_time"]), min(times), rtol=0, atol=1e-14)


class _UndeclaredCheck(Alarms):
    checks: ClassVar[tuple[str, ...]] = ()


def test_a_check_that_settle_returns_and_the_class_does_not_declare_is_refused_by_name():
    """The info's entries are known before tracing (`AbstractModes.checks`), as its kinds are: a
    `settle` returning a check its class does not declare is an error naming both."""
    with jax.enable_x64(True):
        integrator = ll.Integrator(diffrax.Euler())
        modes = _UndeclaredCheck(times=jnp.asarray([0.5, 0.75]))
        with pytest.raises(TypeError, match=r"_UndeclaredCheck\.settle returned the checks \['at_most_two'\].*checks = \(\)"):
            integrate_hybrid(integrator, modes, jnp.zeros(3), None, 1.0)


class _SummedBisection(optimistix.Bisection):
    """Bisection on the sum of a tuple of conditions: diffrax's root find zeroes all but the one it locates."""

    def init(self, fn, y, args, options, f_struct, aux_struct, tags):
        return super().init(_summed(fn), y, args, options, jax.tree.leaves(f_struct)[0], aux_struct, tags)

    def step(self, fn, y, args, options, state, tags):
        return super().step(_summed(fn), y, args, options, state, tags)


def _summed(fn):
    def summed(y, args):
        value, aux = fn(y, args)
        return sum(jax.tree.leaves(value)), aux

    return summed


def test_a_tuple_of_conditions_locates_the_first_in_order_not_in_time():
    """Why the loop's event is the minimum of the guards: diffrax 0.7, given the guards as a
    tuple, locates the first that changed sign within the step in the tuple's order. Here the
    alarm due at 0.75 is located and the one due at 0.5, already past, is lost."""
    with jax.enable_x64(True):
        times = jnp.asarray([0.75, 0.5])
        conditions = tuple((lambda t, y, args, i=i, **kwargs: times[i] - y) for i in range(2))
        root_finder = _SummedBisection(rtol=1e-14, atol=1e-14, flip=True)
        solution = diffrax.diffeqsolve(
            diffrax.ODETerm(lambda t, y, args: jnp.ones_like(y)), diffrax.Euler(), t0=0.0, t1=1.0, dt0=1.0,
            y0=jnp.zeros(()), event=diffrax.Event(conditions, root_finder=root_finder, direction=False),
        )
        assert solution.ts is not None and solution.event_mask is not None
        np.testing.assert_allclose(float(solution.ts[-1]), 0.75, atol=1e-12)
        assert [bool(fired) for fired in solution.event_mask] == [True, False]


@pytest.mark.slow  # 8 s or more of one worker at 42279c7 (docs/testing.md): CI's, not the quick loop's
def test_a_vmapped_batch_of_alarms_matches_each_alone():
    """Under `vmap` every env runs as many segments as the slowest; an env done early idles
    (`IDLE_FRACTION`) and its result is that of its own solve."""
    with jax.enable_x64(True):
        integrator = ll.Integrator(diffrax.Euler())
        times = jnp.asarray([[0.75, 0.5], [2.0, 3.0], [0.1, 0.9]])
        run = lambda t: integrate_hybrid(integrator, Alarms(times=t), jnp.zeros(3), None, 1.0)
        ys, info = jax.jit(jax.vmap(run))(times)
        np.testing.assert_allclose(np.asarray(ys[:, 1:]), np.where(times <= 1.0, times, 0.0), rtol=0, atol=1e-14)
        np.testing.assert_array_equal(np.asarray(info["alarms"]), [2, 0, 2])
        assert bool(jnp.all(info["solver_ok"]))
