"""Moved to `lerax_like.gradients` (`gradcheck`, `GradCheckReport`, `LeafCheck`, `selection_spec`);
the old imports work and warn."""

from .._module_attributes import moved_names


__getattr__ = moved_names(__name__, {
    "lerax_like.gradients": ("GradCheckReport", "LeafCheck", "gradcheck", "selection_spec"),
})
