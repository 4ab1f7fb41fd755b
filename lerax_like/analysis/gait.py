"""Walking gaits and their stability: the step-to-step return map of a passive walker, differentiated.

The return map `P` takes a state just after a heel strike to the state just after the
next one: the stance phase integrated (zero input) up to the heel strike, located as an
event (`front_gap(y) = 0` falling, `lerax_like.physics.walker`), then the walker's
`heel_strike` map. A period-one gait is a fixed point `y* = P(y*)`, found by Newton's
method with the Jacobian `DP` by `jax.jacfwd` through the solve: the event time is
differentiated implicitly, so `DP` is the derivative of the hybrid flow (the saltation
term included), not a finite difference. The gait's stability is read off the
eigenvalues of `DP(y*)` (its Floquet multipliers; a post-impact state confined to a
surface adds zeros), and its sensitivities by the implicit function theorem:

    dy*/dp = (I - DP)^-1 dP/dp,

and for an eigenvalue `lambda` of `DP` with right and left eigenvectors `v`, `w`,
`d lambda = w^H dDP v / (w^H v)` along the total derivative `dDP = D2P dy* + dDP/dp`;
`d|lambda| = Re(conj(lambda) d lambda) / |lambda|`.

Works for any dynamics with `front_gap` and `heel_strike` (the walkers, `RimlessWheel`).
"""

import dataclasses
from typing import NamedTuple, cast

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._segments import segment_solver
from .._types import Array, Float, Scalar, State
from ..integrate import Integrator
from ..physics import AbstractDynamics, AbstractWalkerDynamics


class Step(NamedTuple):
    """One step of the return map: the state after the heel strike, the step's period, and whether it was found."""

    state: Float[Array, " n"]
    period: Scalar
    ok: Array


class Gait(NamedTuple):
    """A period-one gait: the fixed point, its step period, the Jacobian of the return map there and its eigenvalues.

    `eigenvalues` sorted by decreasing modulus; `residual` is `|P(y*) - y*|` (max norm);
    `converged` whether Newton met its tolerance.
    """

    fixed_point: np.ndarray
    period: float
    jacobian: np.ndarray
    eigenvalues: np.ndarray
    residual: float
    converged: bool

    @property
    def stable(self) -> bool:
        return bool(np.max(np.abs(self.eigenvalues)) < 1)


class Sensitivity(NamedTuple):
    """Derivatives of a gait with respect to each physical parameter (by name): of the fixed point and of the
    largest eigenvalue's modulus."""

    fixed_point: dict[str, np.ndarray]
    spectral_radius: dict[str, float]


def _condition(t, y, args, **kwargs):
    del t, kwargs
    return args.front_gap(y)


def step_to_step(
    dynamics: AbstractDynamics, y0: State, *, max_time: float = 20.0, rtol: float = 1e-13, atol: float = 1e-13
) -> Step:
    """The return map `P(y0)`: from `y0` (just after a heel strike) to just after the next heel strike.

    Integrated with `Dopri8` under a PID controller at `rtol`, `atol`, the heel strike
    located by the hybrid loop's segment solve (`lerax_like._segments.segment_solver`, the
    solve every env step with contacts runs): bisection to a few machine epsilons in time.
    `ok` is False when no heel strike happens within `max_time` (the walker fell, or
    stood) or the solve failed. Differentiable in `y0` and in `dynamics` in forward mode
    (`jax.jacfwd`, `jax.jvp`).

    Derivatives: the event's solve ends on the solver's interpolant, whose time derivative
    is off the vector field by about 1e-9 relative (Dopri8 at 1e-13), enough to spoil the
    saltation term (`P`'s Jacobian then misses a rimless wheel's closed form by 6e-10). So
    the located time `T` is held fixed, the stance integrated again to `T` (a step's end, not
    an interpolant), and the time's dependence restored by Newton steps on the gap,
    `T' = T - gap(y(T)) / gap_rate(y(T))`, whose value is `T` and whose derivatives are the
    implicit function theorem's: one step gives the first derivatives, two the second,
    with `y(T + s) = y(T) + f s + (Df f) s**2 / 2`.
    """
    dtype = y0.dtype
    zero_input = jnp.zeros((1,), dtype)
    stance = lambda t, y, args: args.vector_field(t, y, zero_input)
    controller = diffrax.PIDController(rtol=rtol, atol=atol)
    integrator = Integrator(diffrax.Dopri8(), controller, max_steps=100_000)
    no_dip = lambda t0, t1, y0, y1, args: jnp.ones((), dtype)  # the stance has one heel strike, no grazing
    solve = segment_solver(integrator, stance, None, _condition, no_dip, jnp.asarray(max_time, dtype))
    located = solve(jax.lax.stop_gradient(y0), jnp.zeros((), dtype), jax.lax.stop_gradient(dynamics))
    ok = located.result == diffrax.RESULTS.event_occurred
    time = jax.lax.stop_gradient(located.t)
    solution = diffrax.diffeqsolve(
        diffrax.ODETerm(stance), diffrax.Dopri8(), t0=0.0, t1=time, dt0=None, y0=y0, args=dynamics,
        stepsize_controller=controller, max_steps=100_000, adjoint=diffrax.ForwardMode(), throw=False,
    )
    assert solution.ys is not None  # diffeqsolve's default SaveAt(t1=True)
    y = solution.ys[-1]
    walker = cast(AbstractWalkerDynamics, dynamics)  # front_gap and heel_strike: a walker's
    field = lambda z: dynamics.vector_field(time, z, zero_input)
    rate, curvature = jax.jvp(field, (y,), (field(y),))

    def later(shift):  # y(T + shift) to second order in the shift
        return y + rate * shift + curvature * shift**2 / 2

    def newton(shift):
        z = later(shift)
        gap, gap_rate = jax.jvp(walker.front_gap, (z,), (rate + curvature * shift,))
        return shift - gap / gap_rate

    # Two Newton steps: the first gives the time's first derivatives exactly, the second
    # its second derivatives (what `gait_sensitivity` reads through the Jacobian).
    shift = newton(newton(jnp.zeros_like(time)))
    ok = ok & (solution.result == diffrax.RESULTS.successful)
    return Step(walker.heel_strike(later(shift)), time + shift, ok)


step_to_step_jit = eqx.filter_jit(step_to_step)


def _map(dynamics, y):
    return step_to_step(dynamics, y).state


@eqx.filter_jit
def _map_and_jacobian(dynamics, y):
    step = step_to_step(dynamics, y)
    return step, jax.jacfwd(lambda z: _map(dynamics, z))(y)


def find_gait(dynamics: AbstractDynamics, guess: State, *, tolerance: float = 1e-12, max_iterations: int = 30) -> Gait:
    """The period-one gait nearest `guess` by Newton's method on `P(y) - y`, the Jacobian by `jax.jacfwd`.

    Converged when the residual `P(y) - y` is below `tolerance`, or the Newton update is
    and the residual below ten times it (max norms): `P` itself is accurate to about 1e-13 over a step (`step_to_step`'s
    tolerances), which an unstable gait's Newton step amplifies by `(I - DP)^-1`.
    """
    y = jnp.asarray(guess, dtype=jnp.result_type(float))
    converged = False
    for _ in range(max_iterations):
        step, jacobian = _map_and_jacobian(dynamics, y)
        if not bool(step.ok):
            break
        residual = step.state - y
        if float(jnp.max(jnp.abs(residual))) < tolerance:
            converged = True
            break
        update = jnp.linalg.solve(jacobian - jnp.eye(y.shape[0], dtype=y.dtype), -residual)
        y = y + update
        if float(jnp.max(jnp.abs(update))) < tolerance and float(jnp.max(jnp.abs(residual))) < 10 * tolerance:
            converged = True
            break
    step, jacobian = _map_and_jacobian(dynamics, y)
    jacobian = np.asarray(jacobian)
    eigenvalues = np.linalg.eigvals(jacobian)
    eigenvalues = eigenvalues[np.argsort(-np.abs(eigenvalues), kind="stable")]
    residual = float(jnp.max(jnp.abs(step.state - y)))
    return Gait(np.asarray(y), float(step.period), jacobian, eigenvalues, residual, converged and bool(step.ok))


def parameter_names(dynamics: AbstractDynamics) -> list[str]:
    """The dynamics' physical parameters: its floating-point scalar fields."""
    names = []
    for field in dataclasses.fields(dynamics):
        value = getattr(dynamics, field.name)
        if eqx.is_inexact_array(value) and value.shape == ():
            names.append(field.name)
    return names


def _along(dynamics, name):
    """The tangent of `dynamics`' arrays along its parameter `name`: one there, zero in every other."""
    zeros = jax.tree.map(jnp.zeros_like, eqx.filter(dynamics, eqx.is_inexact_array))
    return eqx.tree_at(lambda d: getattr(d, name), zeros, jnp.ones_like(getattr(dynamics, name)))


# The parameter is picked by the tangent, an argument: one compilation serves every parameter,
# where one per parameter's name was compiled before (ten for the compass gait's five).
@eqx.filter_jit
def _parameter_derivative(dynamics, y, along):
    """`dP/dp` at `y` along the parameter that `along` picks (`_along`), by `jax.jvp` (forward mode)."""
    arrays, static = eqx.partition(dynamics, eqx.is_inexact_array)
    return jax.jvp(lambda a: _map(eqx.combine(a, static), y), (arrays,), (along,))[1]


def _jacobian_of(dynamics, y):
    return jax.jacfwd(lambda z: _map(dynamics, z))(y)


@eqx.filter_jit
def _jacobian_derivative(dynamics, y, dy, along):
    """The total derivative of `DP(y*(p), p)` along `p` (picked by `along`): `D2P dy + dDP/dp`, by one `jax.jvp`."""
    arrays, static = eqx.partition(dynamics, eqx.is_inexact_array)
    return jax.jvp(lambda z, a: _jacobian_of(eqx.combine(a, static), z), (y, arrays), (dy, along))[1]


def gait_sensitivity(dynamics: AbstractDynamics, gait: Gait, names: list[str] | None = None) -> Sensitivity:
    """Derivatives of `gait`'s fixed point and of its largest eigenvalue's modulus w.r.t. each parameter in `names`.

    By the implicit function theorem (module docstring); `names` defaults to every
    physical parameter of `dynamics` (`parameter_names`).
    """
    names = parameter_names(dynamics) if names is None else names
    y = jnp.asarray(gait.fixed_point)
    jacobian = gait.jacobian
    n = jacobian.shape[0]
    values, right = np.linalg.eig(jacobian)
    index = int(np.argmax(np.abs(values)))
    lam, v = values[index], right[:, index]
    left_values, left = np.linalg.eig(jacobian.T)
    w = left[:, int(np.argmin(np.abs(left_values - lam)))]  # w^T J = lam w^T
    fixed, radius = {}, {}
    for name in names:
        along = _along(dynamics, name)
        partial = np.asarray(_parameter_derivative(dynamics, y, along))
        dy = np.linalg.solve(np.eye(n) - jacobian, partial)
        fixed[name] = dy
        d_jacobian = np.asarray(_jacobian_derivative(dynamics, y, jnp.asarray(dy), along))
        d_lam = (w @ d_jacobian @ v) / (w @ v)
        radius[name] = float(np.real(np.conj(lam) * d_lam) / np.abs(lam))
    return Sensitivity(fixed, radius)


def walker_scenes() -> list[str]:
    """The registered scenes whose dynamics are walkers (what `lerax-like gait` takes)."""
    from ..physics.walker import AbstractWalkerDynamics
    from .scenes import SCENES

    def is_walker(scene) -> bool:
        dynamics = scene.__annotations__.get("dynamics")
        return isinstance(dynamics, type) and issubclass(dynamics, AbstractWalkerDynamics)

    return sorted(name for name, scene in SCENES.items() if is_walker(scene))


# Digits that the gait's numbers hold. The fixed point and its period: Newton to a residual of
# 1e-12 or less through a Dopri8 solve at 1e-13, 12 digits. The return map's Jacobian, its
# eigenvalues and the fixed point's derivatives, first derivatives through that solve: 10.
# d|lambda|/dp, a second derivative through it: 8 (the rimless wheel's |lambda| = cos(2 alpha)^2
# does not depend on the slope; its computed derivative was -1.8e-9). A number below the last
# digit of the largest of its kind (a vector's components, the eigenvalues) is printed as 0.
FIXED_POINT_DIGITS = 12
DIGITS = 10
SECOND_ORDER_DIGITS = 8


def rounded(values, digits: int) -> np.ndarray:
    """`values` rounded to `digits` significant digits of the largest magnitude among them (round-off to 0)."""
    values = np.asarray(values)
    scale = float(np.max(np.abs(values), initial=0.0))
    if scale == 0 or not np.isfinite(scale):
        return values
    quantum = 10.0 ** (np.floor(np.log10(scale)) - digits + 1)
    parts = (np.real(values), np.imag(values)) if np.iscomplexobj(values) else (values,)
    rounded_parts = [np.round(part / quantum) * quantum + 0.0 for part in parts]  # + 0.0: no -0
    return rounded_parts[0] + 1j * rounded_parts[1] if len(rounded_parts) == 2 else rounded_parts[0]


def _number(value, digits: int) -> str:
    if np.iscomplexobj(value) and np.imag(value) != 0:
        return f"{np.real(value):.{digits}g}{np.imag(value):+.{digits}g}j"
    return f"{float(np.real(value)) + 0.0:.{digits}g}"


def _named(names, values, digits: int) -> str:
    return ", ".join(f"{name} {_number(value, digits)}" for name, value in zip(names, rounded(values, digits)))


def scene_gait(name: str, keywords: dict[str, float] | None = None, *, sensitivity: bool = True) -> str:
    """The period-one gait of the walker scene `name` (built with `keywords`), as text.

    Newton starts at the middle of the scene's starting box (each walker's is about its
    passive gait). With `sensitivity`, also the derivatives of the fixed point and of the
    largest eigenvalue's modulus w.r.t. every physical parameter. Each state component is
    named (the dynamics' `state_names`); numbers are printed at the digits they hold
    (`FIXED_POINT_DIGITS`, `DIGITS`, `SECOND_ORDER_DIGITS`), round-off as 0.
    """
    from .scenes import make

    with jax.enable_x64(True):  # a gait's digits need float64
        scene = make(name, **(keywords or {}))
        low, high = scene.initial_bounds
        dynamics = jax.tree.map(
            lambda leaf: jnp.asarray(leaf, jnp.float64) if eqx.is_inexact_array(leaf) else leaf, scene.dynamics
        )
        gait = find_gait(dynamics, (jnp.asarray(low, jnp.float64) + jnp.asarray(high, jnp.float64)) / 2)
        derivatives = gait_sensitivity(dynamics, gait) if sensitivity and gait.converged else None
    names = getattr(dynamics, "state_names", None) or tuple(f"y[{i}]" for i in range(len(gait.fixed_point)))
    eigenvalues = rounded(gait.eigenvalues, DIGITS)
    lines = [
        f"{name}: period-one gait ({'converged' if gait.converged else 'NOT converged'}, residual {gait.residual:.1e})",
        f"  fixed point (just after heel strike): {_named(names, gait.fixed_point, FIXED_POINT_DIGITS)}",
        f"  step period: {gait.period:.{FIXED_POINT_DIGITS}g}",
        f"  eigenvalues of the return map's Jacobian: {', '.join(_number(v, DIGITS) for v in eigenvalues)}",
        f"  {'stable' if gait.stable else 'unstable'}: largest modulus {_number(np.max(np.abs(eigenvalues)), DIGITS)}",
    ]
    if derivatives is not None:
        # d|lambda|/dp across parameters of different units: rounded as elasticities p d|lambda|/dp.
        values = {p: float(getattr(dynamics, p)) for p in derivatives.spectral_radius}
        elasticities = rounded([values[p] * d for p, d in derivatives.spectral_radius.items()], SECOND_ORDER_DIGITS)
        lines.append("  derivatives (implicit function theorem):")
        for (parameter, value), elasticity in zip(derivatives.fixed_point.items(), elasticities):
            raw = derivatives.spectral_radius[parameter]
            radius = elasticity / values[parameter] if values[parameter] != 0 else raw
            lines.append(f"    d fixed point / d {parameter}: {_named(names, value, DIGITS)}")
            lines.append(f"    d |largest eigenvalue| / d {parameter}: {_number(radius, SECOND_ORDER_DIGITS)}")
    return "\n".join(lines)


__all__ = ["Gait", "Sensitivity", "Step", "find_gait", "gait_sensitivity", "parameter_names", "scene_gait", "step_to_step", "step_to_step_jit", "walker_scenes"]
