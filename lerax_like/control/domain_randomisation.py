"""Domain randomisation on CartPoleContinuous: one balancing policy trained over a batch of pole masses.

The experiment of `notebooks/domain_randomisation.ipynb`, `tests/test_domain_randomisation.py`
and `benchmarks/domain_randomisation.py`, in one place so that the three run the same
recipe. A policy is trained either at one pole mass (the nominal 0.1 kg) or over a batch
of envs whose pole masses are drawn from a range (each env of the vmapped batch carries
its own `pole_mass` leaf), then run in the ordinary env (12 degree and 2.4 m thresholds)
at pole masses inside and outside that range.
"""

import math

import equinox as eqx
import jax.numpy as jnp
import jax.random as jr

from .._types import Array, Float, Key, Scalar
from ..scenes import CartPoleContinuous
from .learning import MLPPolicy, episode_lengths, train_policy_curriculum

# The randomised policy's pole masses are uniform in this range (kg); the nominal
# policy's is CartPole's own. The range lies where the nominal policy fails (between 3
# and 6.4 kg), so that masses outside it on both sides say something: lighter ones down
# to the nominal mass and below, heavier ones that a controller designed for them can
# still balance with the 10 N motor (a linear-quadratic regulator, up to 16 kg).
TRAINING_MASS_RANGE = (3.0, 8.0)
NOMINAL_MASS = 0.1
# Stages of the horizon curriculum (env steps of 0.02 s), Adam steps and learning rates.
HORIZONS = (50, 100, 200)
ITERATIONS = (60, 30, 30)
LEARNING_RATES = (3e-3, 1e-3, 1e-3)
# Training starts per coordinate (x, x_dot, theta, theta_dot). The angle stays within
# 0.1: holding a pole at theta needs a force of about (cart_mass + pole_mass) g tan(theta),
# so at 8 kg starts at 0.2 rad are beyond the 10 N motor and teach nothing but a fall.
# The cart's wide starts excite its slow mode, which otherwise grows unseen over the
# 4 s of the longest stage: trained from starts within 0.05 in every coordinate, the
# policy let an oscillation of about 3 s grow until it dropped 8 kg poles after 5 to 9 s.
INITIAL_SPREAD = (0.5, 0.5, 0.1, 0.1)


def cart_cost(y: Float[Array, " 4"]) -> Scalar:
    """Quadratic cost on the cart's position and velocity, subtracted from the smooth reward
    `cos(theta) - 0.001 |u|` during training: that reward does not see the cart, which then
    drifts out of the 2.4 m track within an episode's 10 s."""
    return 0.1 * y[0] ** 2 + 0.1 * y[1] ** 2


def training_envs(pole_masses: Float[Array, " num_envs"]) -> CartPoleContinuous:
    """A batch of training envs along axis 0, one per pole mass: smooth reward, thresholds
    at infinity (a smooth return to differentiate)."""
    inf = math.inf
    return eqx.filter_vmap(
        lambda pole_mass: CartPoleContinuous(
            pole_mass=pole_mass, reward="smooth", theta_threshold_radians=inf, x_threshold=inf
        )
    )(pole_masses)


def train_balancing_policy(
    pole_mass: float | Float[Array, " num_envs"], *, key: Key, num_envs: int = 256
) -> tuple[MLPPolicy, tuple[Array, ...]]:
    """An MLP (two hidden layers of 32) trained by the curriculum above on `num_envs`
    vmapped envs, all at one `pole_mass` or each at its own (an array of `num_envs`).

    Both cases train a batch of envs (the nominal one `num_envs` copies of one mass), so
    that they share one compiled update.

    Returns the policy and each stage's mean return per iteration.
    """
    policy_key, training_key = jr.split(key)
    pole_masses = jnp.broadcast_to(jnp.asarray(pole_mass, dtype=float), (num_envs,))
    return train_policy_curriculum(
        training_envs(pole_masses),
        MLPPolicy(4, 1, width=32, key=policy_key),
        key=training_key,
        num_envs=num_envs,
        horizons=HORIZONS,
        iterations=ITERATIONS,
        learning_rates=LEARNING_RATES,
        initial_spread=jnp.asarray(INITIAL_SPREAD),
        env_axis=0,
        state_cost=cart_cost,
    )


def balanced_fractions(
    policy, pole_masses, *, key: Key, num_starts: int = 100, max_steps: int = 500
) -> dict[float, float]:
    """For each pole mass, the fraction of `num_starts` random starts of the ordinary
    `CartPoleContinuous` that `policy` keeps alive for `max_steps` steps (the same starts
    at every mass)."""
    fractions = {}
    for pole_mass in pole_masses:
        lengths = episode_lengths(
            CartPoleContinuous(pole_mass=pole_mass), policy, key=key, num_starts=num_starts, max_steps=max_steps
        )
        fractions[float(pole_mass)] = int(jnp.sum(lengths >= max_steps)) / num_starts
    return fractions
