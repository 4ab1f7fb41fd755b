"""The figure of docs/friction.md: a stick-slip trajectory and its gradient against finite differences.

    python docs/figures/friction.py      # writes docs/figures/friction.png (needs matplotlib)

The friction cart-pole (`CartPoleContinuous` with `CartFriction`, mu_s = 0.3, mu_k = 0.15, a
0.3 kg pole let go at rest from 1 rad, no force, Tsit5): the cart's speed over 1.2 s with its
located switches, and the derivative of a rollout loss with respect to mu_s and mu_k across a
sweep, by reverse-mode AD and by central differences (step 1e-6).
"""

import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

import lerax_like as ll  # noqa: E402


STEPS = 60


def make_env(mu_s, mu_k):
    return ll.CartPoleContinuous(
        cart_static_friction=mu_s, cart_kinetic_friction=mu_k, pole_mass=0.3,
        x_threshold=jnp.inf, theta_threshold_radians=jnp.inf, solver="tsit5",
    )


def run(theta):
    """States, switch counts and times over STEPS steps at `theta = (mu_s, mu_k)`."""
    env = eqx.tree_at(
        lambda e: (e.friction[0].cart_static_friction, e.friction[0].cart_kinetic_friction),
        make_env(0.3, 0.15), (theta[0], theta[1]),
    )
    y0 = jnp.array([0.0, 0.0, 1.0, 0.0])
    return ll.rollout(env, ll.EnvState(y=y0, steps=jnp.zeros((), dtype=int)), jnp.zeros((STEPS, 1)))


def loss(theta):
    ys, _ = run(theta)
    return jnp.sum(ys[:, 0] ** 2 + ys[:, 1] ** 2) + 0.1 * jnp.sum(jnp.cos(ys[:, 2]))


def main():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ys, info = jax.jit(run)(jnp.array([0.3, 0.15]))
    dt = 0.02
    t = dt * np.arange(1, STEPS + 1)
    switched = np.asarray(info["switches"]) > 0
    times = dt * np.nonzero(switched)[0] + np.asarray(info["first_switch_time"])[switched]

    sweep = np.linspace(0.26, 0.34, 9)
    h = 1e-6
    gradient = jax.jit(jax.vmap(jax.grad(loss)))
    values = jax.jit(jax.vmap(loss))
    panels = []
    for index, name in enumerate(("mu_s", "mu_k")):
        base = np.tile([0.3, 0.15], (len(sweep), 1))
        base[:, index] = sweep if index == 0 else sweep / 2
        ad = np.asarray(gradient(jnp.asarray(base)))[:, index]
        shift = np.zeros(2)
        shift[index] = h
        fd = (np.asarray(values(jnp.asarray(base + shift))) - np.asarray(values(jnp.asarray(base - shift)))) / (2 * h)
        panels.append((name, base[:, index], ad, fd))
        print(name, "largest relative AD/FD difference", float(np.max(np.abs(ad - fd) / np.abs(fd))))

    figure, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    axes[0].plot(np.concatenate([[0.0], t]), np.concatenate([[0.0], np.asarray(ys[:, 1])]), label="cart speed (m/s)")
    axes[0].plot(np.concatenate([[0.0], t]), np.concatenate([[0.0], np.asarray(ys[:, 0])]), label="cart position (m)")
    for time in times:
        axes[0].axvline(time, color="grey", lw=0.8, ls="--")
    axes[0].set_xlabel("time (s); dashed: located switches")
    axes[0].set_title("stick-slip of the cart under a falling pole")
    axes[0].legend(fontsize=8)
    for axis, (name, x, ad, fd) in zip(axes[1:], panels):
        axis.plot(x, fd, "o", label="central differences", ms=7, mfc="none")
        axis.plot(x, ad, "x", label="AD (reverse mode)")
        axis.set_xlabel(name)
        axis.set_title(f"d loss / d {name}")
        axis.legend(fontsize=8)
    figure.tight_layout()
    path = pathlib.Path(__file__).with_suffix(".png")
    figure.savefig(path, dpi=110)
    print("wrote", path)


if __name__ == "__main__":
    main()
