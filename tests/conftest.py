"""Shared fixtures and options (`--slow`); shared helpers are in tests/support."""

import os
import sys

# One BLAS thread, set before numpy loads (as nlp/__init__ does for the CLI): on the
# shared 2-core machine threaded BLAS made small dense solves ~100x slower (measured).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest

# the shared helpers are the package tests/support: `from support.frames import shear_K`
# from any test folder
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def pytest_addoption(parser):
    parser.addoption(
        "--slow", action="store_true", default=False,
        help="also run the tests marked @pytest.mark.slow (CI does; the default run skips them)")


def pytest_collection_modifyitems(config, items):
    # The default run is the fast set; `--slow` (CI) or an explicit `-m` expression runs the rest.
    if config.getoption("--slow") or config.getoption("markexpr"):
        return
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item.get_closest_marker("slow") is None]


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
