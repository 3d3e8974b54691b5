"""Screening solves (IPOPT tol 1e-5) with the best starts polished at the full tolerance:
the search's best is a full-tolerance minimum, checked by its first-order conditions
and against a full-tolerance solve from the same start."""

import numpy as np
import pytest

from support.cases import write_case
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.solve.stopping import SCREEN_TOL
from nlp.solve.search import POLISH, SearchConfig, scatter_search, solve_start


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    path, _ = write_case(str(tmp_path_factory.mktemp("case")), noise=0.02, seed=1,
                         frequencies={"method": "half_power", "k": 2.0, "fmax": 7.0})
    return build_problem(assemble(load_case(path)))


def _projected_gradient(problem, z):
    """J^T r on the parameters that are not at a bound (zero at an interior minimum)."""
    r, J = problem.residuals(z)
    g = J.T @ r
    lo, hi = problem.bounds
    free = (z > lo + 1e-6 * (hi - lo)) & (z < hi - 1e-6 * (hi - lo))
    return g[free]


def test_screened_search_polishes_the_best(problem):
    assert problem.can_screen and SCREEN_TOL > 1e-8
    res = scatter_search(problem, SearchConfig(starts=14, seed=3, executor="serial"))
    best_i = next(i for i, r in zip(res.indices, res.results) if r is res.best)
    conv = sorted((r.f, i) for i, r in zip(res.indices, res.results) if r.success)
    assert 0 < len(res.polished) <= POLISH
    assert set(res.polished) == {i for _, i in conv[:POLISH]} and best_i in res.polished
    # a full-tolerance solve from the best's start reaches the same minimum
    full = solve_start(problem, res.best.z0)
    assert full.success and res.best.f == pytest.approx(full.f, rel=1e-9)
    # first-order condition at the polished best: on the free parameters the gradient
    # J^T r vanishes (1e-5 of its size at the start; a check independent of IPOPT's)
    r0, J0 = problem.residuals(res.best.z0)
    g = _projected_gradient(problem, res.best.z)
    assert np.abs(g).max() <= 1e-5 * np.abs(J0.T @ r0).max()


def test_screening_stops_earlier_than_the_full_tolerance(problem):
    from nlp.solve.search import start_points
    starts, _ = start_points(problem, SearchConfig(starts=8, seed=5))
    pairs = [(solve_start(problem, z, screen=True), solve_start(problem, z)) for z in starts]
    pairs = [(s, f) for s, f in pairs if s.success and f.success]
    assert len(pairs) >= 4
    assert sum(s.iterations for s, _ in pairs) < sum(f.iterations for _, f in pairs)
    for s, f in pairs:  # screening stops on the way to the same minimum, a little higher
        assert s.iterations <= f.iterations
        assert s.f >= f.f * (1 - 1e-9) and s.f == pytest.approx(f.f, rel=1e-4)
