"""Repository-wide pytest hooks (tests/conftest.py holds the tests' fixtures)."""

import pytest


def pytest_collection_modifyitems(config, items):
    # Every notebook run by nbmake trains, fits or studies something: all take more than
    # about 20 s on 2 cores, so all leave the quick loop (python -m pytest -m "not slow").
    for item in items:
        if item.path.suffix == ".ipynb":
            item.add_marker(pytest.mark.slow)
