"""Tests run in float64 with strict dtype promotion, as diffrax's own suite does."""

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")


def tree_allclose(x, y, *, rtol=1e-12, atol=0.0) -> bool:
    """Whether two pytrees have the same structure and all leaves are close."""
    x_leaves, x_def = jax.tree.flatten(x)
    y_leaves, y_def = jax.tree.flatten(y)
    if x_def != y_def:
        return False
    return all(
        np.allclose(np.asarray(a), np.asarray(b), rtol=rtol, atol=atol) for a, b in zip(x_leaves, y_leaves)
    )


def relative_error(estimate, reference) -> float:
    estimate = np.asarray(estimate, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    return float(np.max(np.abs(estimate - reference)) / max(np.max(np.abs(reference)), 1e-300))


@pytest.fixture
def getkey():
    """A fresh PRNG key on each call, from a fixed seed: keys are never reused."""
    keys = iter(jax.random.split(jax.random.key(0), 10_000))
    return lambda: next(keys)


__all__ = ["jnp", "relative_error", "tree_allclose"]


def pytest_collection_modifyitems(config, items):
    # Every notebook run by nbmake trains, fits or studies something: all take more than
    # about 20 s on 2 cores, so all leave the quick loop (python -m pytest -m "not slow").
    # (Here rather than in notebooks/: a second module named conftest would shadow this
    # one for the tests' `from conftest import ...`; the top level is fixed.)
    for item in items:
        if item.path.suffix == ".ipynb":
            item.add_marker(pytest.mark.slow)


# CI installs the test extra, which holds every optional dependency the tests import; a
# test skipped there for a missing one is a broken install, not a test that does not
# apply, and must fail. A contributor without (say) stable-baselines3 still gets a skip.
# A skip is for a missing dependency when its reason is pytest.importorskip's ("could not
# import ...") or carries an install hint ("pip install ..."), as every such skip here does.
MISSING_DEPENDENCY = ("could not import", "pip install")


def _in_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def _fail_if_missing_dependency(report):
    if not (report.skipped and _in_ci() and isinstance(report.longrepr, tuple)):
        return report
    reason = report.longrepr[2].removeprefix("Skipped: ")
    if any(marker in reason for marker in MISSING_DEPENDENCY):
        report.outcome = "failed"
        report.longrepr = f"CI is set, and the test extra should install every optional dependency: {reason}"
    return report


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector):
    # A module-level pytest.importorskip skips the whole module at collection.
    return _fail_if_missing_dependency((yield))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    return _fail_if_missing_dependency((yield))
