"""Moved to `lerax_like.gradients` (the estimators of a smoothed objective's gradient and their
reference); the old imports work and warn."""

from .._module_attributes import moved_names


__getattr__ = moved_names(__name__, {
    "lerax_like.gradients": ("ESTIMATORS", "Evaluators", "alpha_weight", "estimate_gradients", "per_sample_statistics"),
})
