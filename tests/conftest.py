"""Shared fixtures: the paper's four-story frame (Table 1) and random systems."""

import os
import sys

# One BLAS thread, set before numpy loads (as nlp/__init__ does for the CLI): on the
# shared 2-core machine threaded BLAS made small dense solves ~100x slower (measured).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "scripts"))
for _d in ("", "case", "diagnosis"):
    sys.path.insert(0, os.path.join(HERE, _d))

# shear-frame stiffness written independently of the package (one copy, with the
# independent simulator of the noise tests)
from noise_sim import shear_K  # noqa: E402,F401

TABLE1_INITIAL_M = np.full(4, 4.64)
TABLE1_INITIAL_K = np.array([1019.0, 1217.0, 1420.0, 2473.0])


def frame_parameter_set(m, k, damping):
    """ParameterSet of a shear frame: free story stiffness changes, fixed masses, and the
    damping model's own parameters (for tests that build an UpdatingProblem by hand)."""
    from nlp.model.parameters import Parameter, ParameterSet

    n = len(k)
    ps = [Parameter(f"k{i + 1}", "stiffness", 0.0, -0.5, 1.0, nominal=k[i]) for i in range(n)]
    ps += [Parameter(f"m{i + 1}", "mass", 0.0, -0.5, 1.0, fixed=True, nominal=m[i])
           for i in range(n)]
    lo, hi = damping.default_bounds()
    ps += [Parameter(nm, "damping", t, a, b) for nm, t, a, b in
           zip(damping.names, damping.initial(), lo, hi)]
    return ParameterSet(tuple(ps), n, n)


def random_system(n, rng):
    """Random SPD M, K and a non-proportional SPD C."""
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    K = 100 * (B @ B.T + n * np.eye(n))
    D = rng.standard_normal((n, n))
    C = 0.5 * (D @ D.T) + 0.1 * np.eye(n)
    return M, C, K


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
