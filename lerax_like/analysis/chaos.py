"""Moved: the float32 digit loss and the variance crossover are in
`lerax_like.analysis.gradient_variance` (taking values: the envs by dtype and the cost's weights),
the finite-time Lyapunov exponents in `lerax_like.gradients` (taking the step map); the old
imports work and warn."""

from .._module_attributes import moved_names


__getattr__ = moved_names(__name__, {
    "lerax_like.analysis.gradient_variance": (
        "precision_at_horizons", "precision_loss", "truncated_gradients", "variance_crossover",
    ),
    "lerax_like.gradients": ("finite_time_lyapunov",),
})
