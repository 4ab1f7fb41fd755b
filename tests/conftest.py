"""Tests run in float64 with strict dtype promotion, as diffrax's own suite does."""

import importlib
import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest


jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

# Scenes that tests define, as a contributor would (`tests/<name>/scene.py`, which calls
# `lerax_like.register_scene`): imported here, before collection, so that every test
# parametrised over `lerax_like.SCENES` covers them with no line changed elsewhere.
TEST_SCENES = tuple(
    importlib.import_module(f"{path.parent.name}.scene")
    for path in sorted(pathlib.Path(__file__).parent.glob("*/scene.py"))
)


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
