"""The studies' and gradient tools' old import paths: each name still imports, warns naming its
new place, and is the very object found there; our own modules import with no warning."""

import importlib
import subprocess
import sys
import warnings

import pytest


# (where a name was importable at 5cbcda0, the name, where it lives now)
MOVED = [
    ("lerax_like.analysis", "gradcheck", "lerax_like.gradients"),
    ("lerax_like.analysis", "GradCheckReport", "lerax_like.gradients"),
    ("lerax_like.analysis", "sensitivity_signs", "lerax_like.gradients"),
    ("lerax_like.analysis.gradcheck", "LeafCheck", "lerax_like.gradients"),
    ("lerax_like.analysis.gradient_estimators", "estimate_gradients", "lerax_like.gradients"),
    ("lerax_like.analysis.gradient_accuracy", "trajectory_sensitivity", "lerax_like.gradients"),
    ("lerax_like.analysis.gradient_variance", "alpha_weight", "lerax_like.gradients"),
    ("lerax_like.analysis.chaos", "finite_time_lyapunov", "lerax_like.gradients"),
    ("lerax_like.analysis.chaos", "precision_loss", "lerax_like.analysis.gradient_variance"),
    ("lerax_like.analysis.rollout_cost", "stage_costs", "lerax_like.analysis.gradient_variance"),
    ("lerax_like.analysis.report", "write_study", "lerax_like.analysis.study"),
    ("lerax_like.analysis.report", "CSV_COLUMNS", "lerax_like.analysis.study"),
    ("lerax_like.analysis.report", "write_gradient_study", "lerax_like.analysis.gradient_accuracy"),
    ("lerax_like.analysis.report", "format_orders", "lerax_like.analysis.tables"),
    ("lerax_like.analysis.report", "plot_work_precision", "lerax_like.analysis.figures"),
    ("lerax_like.analysis.report", "cheapest_at", "lerax_like.analysis.verdict"),
    ("lerax_like.analysis.report", "PLOT_HINT", "lerax_like.analysis.recording"),
]


@pytest.mark.parametrize("old, name, new", MOVED, ids=[f"{old}.{name}" for old, name, _ in MOVED])
def test_a_moved_name_imports_and_warns_with_its_new_place(old, name, new):
    with pytest.warns(DeprecationWarning, match=f"{new}.{name}"):
        value = getattr(importlib.import_module(old), name)
    assert value is getattr(importlib.import_module(new), name)


# Every public name of these modules at 5cbcda0 (its own definitions and `X as X` re-exports).
BEFORE = {
    "lerax_like.analysis.report": (
        "CSV_COLUMNS GRADIENT_CSV_COLUMNS PLOT_HINT UNRESOLVED_SPREAD UNRESOLVED_TIMING_FACTOR VERDICT_TARGETS "
        "cheapest_at failures format_gradient_table format_orders format_table group_settings matplotlib_available "
        "order_disagreements order_guide plot_gradient_work_precision plot_work_precision read_csv timing_unresolved "
        "write_csv write_gradient_study write_json write_study"
    ),
    "lerax_like.analysis.rollout_cost": (
        "POLICIES action_size active_parameters build_env initial_state lqr_gain nominal_gain nominal_parameters "
        "objective policy_action stage_costs step_state"
    ),
    "lerax_like.analysis.chaos": "finite_time_lyapunov precision_at_horizons precision_loss truncated_gradients "
                                 "variance_crossover",
    "lerax_like.analysis.gradient_variance": (
        "CONTACT_GAP DESCRIPTIONS ESTIMATORS Evaluators GRADIENT_VARIANCE_CSV_COLUMNS GradientVarianceConfig "
        "GradientVarianceResult POLICIES action_size active_parameters alpha_weight build_env estimate_gradients "
        "file_stem finite_time_lyapunov format_gradient_variance_table initial_state lqr_gain nominal_gain "
        "nominal_parameters objective per_sample_statistics plot_gradient_variance policy_action precision_at_horizons "
        "precision_loss run_gradient_variance stage_costs step_state summary truncated_gradients variance_crossover "
        "write_gradient_variance"
    ),
    "lerax_like.analysis.study": (
        "SCHEDULES ScheduleReference SolverSweep StudyConfig StudyResult default_sweeps environment_record "
        "evaluations_per_step run_study sweeps_for tolerance_pairs"
    ),
    "lerax_like.analysis.gradient_accuracy": (
        "GradientStudyConfig Loss default_gradient_sweeps gradient_scenes gradient_sweeps_for gradient_work_precision "
        "mean_squared_state reference_integrator run_gradient_study sensitivity_signs trajectory_loss "
        "trajectory_sensitivity with_integrator"
    ),
}


@pytest.mark.parametrize("module", sorted(BEFORE))
def test_every_name_of_the_old_modules_still_imports(module):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        found = importlib.import_module(module)
        missing = [name for name in BEFORE[module].split() if not hasattr(found, name)]
    assert not missing


def test_our_own_modules_import_with_no_deprecation_warning():
    # A fresh interpreter: a module imported earlier in this process would not warn again.
    code = (
        "import lerax_like, lerax_like.analysis, lerax_like.cli, lerax_like.gradients, "
        "lerax_like.analysis.gradient_variance, lerax_like.analysis.study, lerax_like.analysis.tables"
    )
    subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c", code], check=True)


def test_the_old_gradcheck_module_does_not_shadow_the_function():
    # `lerax_like.analysis.gradcheck` is both the old module and the old name of the function: an
    # import of the module first must leave the name the function (a fresh interpreter: the order
    # of imports is the point).
    code = (
        "import lerax_like.analysis.gradcheck\n"
        "from lerax_like.analysis import gradcheck\n"
        "from lerax_like.analysis.gradcheck import gradcheck as from_module\n"
        "import lerax_like.gradients\n"
        "assert gradcheck is from_module is lerax_like.gradients.gradcheck, gradcheck\n"
    )
    subprocess.run([sys.executable, "-W", "ignore::DeprecationWarning", "-c", code], check=True)
