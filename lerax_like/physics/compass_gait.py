"""The compass-gait biped (Goswami, Thuilot and Espiau, 1996)."""

from typing import ClassVar, final

import equinox as eqx
import jax
import jax.numpy as jnp

from .._fields import POSITIVE
from .._types import Array, Float, Input, Scalar, ScalarLike, State
from .walker import SLOPE, AbstractWalkerDynamics, swing_gap


@final
class CompassGaitDynamics(AbstractWalkerDynamics):
    """Two rigid legs of distributed mass hinged at a hip mass, walking down a slope.

    A. Goswami, B. Thuilot and B. Espiau, "Compass-like biped robot part I: stability and
    bifurcation of passive gaits", INRIA research report 2996 (1996); IJRR 17(12) (1998).
    Each leg has its mass `leg_mass` (m) at `lower_length` (a) from its foot and
    `upper_length` (b) from the hip (leg length `l = a + b`), the hip mass `hip_mass` (m_H);
    the slope is `slope` radians, gravity `gravity`. Defaults the report's nominal walker:
    a = b = 0.5 m, m = 5 kg, m_H = 10 kg, a slope of 3 degrees.

    State `y = [theta_s, theta_w, theta_s_dot, theta_w_dot]`: the stance and swing legs'
    angles from the vertical, each the angle of the vector from its foot to the hip,
    positive downhill (the report's `theta_s`, `theta_ns` with the sign of walking). In
    stance `M(q) q'' = rhs` with `q = [theta_s, theta_w]`, `delta = theta_s - theta_w`,

        M   = [[m a**2 + (m_H + m) l**2, -m l b cos delta], [-m l b cos delta, m b**2]]
        rhs = [ m l b sin(delta) theta_w_dot**2 + g (m a + (m_H + m) l) sin theta_s - u,
               -m l b sin(delta) theta_s_dot**2 - g m b sin theta_w + u]

    `u[0]` a hip torque, on the swing leg positive downhill and its reaction on the stance
    leg. The swing foot is on the slope when the legs are symmetric about its normal,
    `theta_s + theta_w = 2 slope`: the heel strike with the stance leg past the normal
    (`front_gap`, the swing foot's scuffing at mid-stance ignored, as in the report). Its
    map (`heel_strike`) exchanges the legs and conserves the angular momentum of the
    whole walker about the new stance foot and of the new swing leg about the hip.
    """

    velocity_indices: ClassVar[tuple[int, ...]] = (2, 3)
    # The state's components by name, as the docstring writes them (`lerax-like gait` prints them).
    state_names: ClassVar[tuple[str, ...]] = ("theta_s", "theta_w", "theta_s_dot", "theta_w_dot")

    lower_length: Scalar = eqx.field(default=0.5, converter=POSITIVE)
    upper_length: Scalar = eqx.field(default=0.5, converter=POSITIVE)
    leg_mass: Scalar = eqx.field(default=5.0, converter=POSITIVE)
    hip_mass: Scalar = eqx.field(default=10.0, converter=POSITIVE)
    slope: Scalar = eqx.field(default=3 * jnp.pi / 180, converter=SLOPE)
    gravity: Scalar = eqx.field(default=9.81, converter=POSITIVE)

    @property
    def leg_length(self) -> Scalar:
        return self.lower_length + self.upper_length

    def coordinates(self, y: State) -> tuple[Float[Array, " 2"], Float[Array, " 2"]]:
        return y[:2], y[2:]

    def mass_matrix(self, q: Float[Array, " 2"]) -> Float[Array, "2 2"]:
        a, b, l, m = self.lower_length, self.upper_length, self.leg_length, self.leg_mass
        coupling = -m * l * b * jnp.cos(q[0] - q[1])
        return jnp.stack([
            jnp.stack([m * a**2 + (self.hip_mass + m) * l**2, coupling]),
            jnp.stack([coupling, m * b**2 * jnp.ones_like(coupling)]),
        ])

    def vector_field(self, t: ScalarLike, y: State, u: Input) -> State:
        del t
        q, q_dot = self.coordinates(y)
        a, b, l, m, g = self.lower_length, self.upper_length, self.leg_length, self.leg_mass, self.gravity
        sin_delta = jnp.sin(q[0] - q[1])
        rhs = jnp.stack([
            m * l * b * sin_delta * q_dot[1] ** 2 + g * (m * a + (self.hip_mass + m) * l) * jnp.sin(q[0]) - u[0],
            -m * l * b * sin_delta * q_dot[0] ** 2 - g * m * b * jnp.sin(q[1]) + u[0],
        ])
        return jnp.concatenate([q_dot, jnp.linalg.solve(self.mass_matrix(q), rhs)])

    def energy(self, y: State) -> Scalar:
        """Kinetic plus potential energy, the height from the stance foot; conserved in stance with `u = 0`."""
        q, q_dot = self.coordinates(y)
        a, b, l, m = self.lower_length, self.upper_length, self.leg_length, self.leg_mass
        potential = self.gravity * ((m * a + (self.hip_mass + m) * l) * jnp.cos(q[0]) - m * b * jnp.cos(q[1]))
        return q_dot @ self.mass_matrix(q) @ q_dot / 2 + potential

    def front_gap(self, y: State) -> Scalar:
        q, q_dot = self.coordinates(y)
        return swing_gap(self.slope - q[0], 2 * self.slope - q[0] - q[1], -q_dot[0] - q_dot[1])

    def stance_angle(self, y: State) -> Scalar:
        return y[0] - self.slope

    def hip_speed(self, y: State) -> Scalar:
        return self.leg_length * jnp.cos(y[0] - self.slope) * y[2]

    def points(self, q: Float[Array, " 2"]) -> Float[Array, "4 2"]:
        """Stance leg's mass, hip, swing leg's mass and swing foot, from the stance foot (x downhill, y up)."""
        a, b, l = self.lower_length, self.upper_length, self.leg_length
        stance = jnp.stack([jnp.sin(q[0]), jnp.cos(q[0])])
        swing = jnp.stack([jnp.sin(q[1]), jnp.cos(q[1])])
        hip = l * stance
        return jnp.stack([a * stance, hip, hip - b * swing, hip - l * swing])

    def _momenta(self, q: Float[Array, " 2"], q_dot: Float[Array, " 2"], about: Float[Array, " 2"], legs: int):
        """Angular momenta about `about` of the masses `[stance leg, hip, swing leg][:legs]`."""
        positions, velocities = jax.jvp(self.points, (q,), (q_dot,))
        masses = jnp.stack([self.leg_mass, self.hip_mass, self.leg_mass])
        arm = positions[:3] - about
        moments = masses * (arm[:, 0] * velocities[:3, 1] - arm[:, 1] * velocities[:3, 0])
        return jnp.sum(moments[:legs]) if legs == 3 else moments[0]

    def heel_strike(self, y: State) -> State:
        """The legs' exchange, momentum-conserving: the report's `Q+(alpha) q_dot+ = Q-(alpha) q_dot-`.

        Conserved through the impulse at the landing foot: the whole walker's angular
        momentum about that foot, and the new swing leg's (the old stance leg's, which
        the hip joint holds by a force through the hip only) about the hip. Both are
        linear in the velocities; `Q+` is read off by differentiation.
        """
        q, q_dot = self.coordinates(y)
        foot, hip = self.points(q)[3], self.points(q)[1]
        before = jnp.stack([self._momenta(q, q_dot, foot, 3), self._momenta(q, q_dot, hip, 1)])
        q_after = q[::-1]
        # After the impact the new stance foot is the origin of `points(q_after)`, the hip
        # at the same place relative to it; the old stance leg's mass is the new swing leg's.
        new_hip = self.points(q_after)[1]

        def after(v):
            whole = self._momenta(q_after, v, jnp.zeros(2, y.dtype), 3)
            positions, velocities = jax.jvp(self.points, (q_after,), (v,))
            arm = positions[2] - new_hip
            swing = self.leg_mass * (arm[0] * velocities[2, 1] - arm[1] * velocities[2, 0])
            return jnp.stack([whole, swing])

        matrix = jax.jacfwd(after)(jnp.zeros_like(q_dot))
        return jnp.concatenate([q_after, jnp.linalg.solve(matrix, before)])


__all__ = ["CompassGaitDynamics"]
