"""Moved: the gradient-variance study's objective is in `lerax_like.analysis.gradient_variance`,
whose helpers take values (`build_env(scene, scene_kwargs, solver, dtype)`, `initial_state(env,
start, seed)`, `nominal_gain(env64, feedback_gain, state_weight, action_weight)`); the old
imports work and warn."""

from .._module_attributes import moved_names


__getattr__ = moved_names(__name__, {
    "lerax_like.analysis.gradient_variance": (
        "POLICIES", "action_size", "active_parameters", "build_env", "initial_state", "lqr_gain", "nominal_gain",
        "nominal_parameters", "objective", "policy_action", "stage_costs", "step_state",
    ),
})
