"""Levenberg-Marquardt on the determined directions (nlp.solve.lm) against closed-form
least-squares solutions, and the chunked normal equations against J^T J."""

import numpy as np
import pytest
import yaml
from scipy.optimize import least_squares, lsq_linear

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.frf.backends import sparse
from nlp.solve.lm import determined_directions, levenberg_marquardt
from nlp.solve.problem import UpdatingProblem
from nlp.testing.tall import case_dict, tall_frame


def _linear(A, b):
    """normal(z) -> (f, J^T r, J^T J) and value(z) -> f of r = A z - b."""
    def normal(z):
        r = A @ z - b
        return 0.5 * float(r @ r), A.T @ r, A.T @ A

    def value(z):
        r = A @ z - b
        return 0.5 * float(r @ r)
    return normal, value


def _data(seed=0, m=60, n=6, noise=0.01):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, n))
    return A, A @ rng.uniform(-0.3, 0.3, n) + noise * rng.standard_normal(m)


def test_linear_least_squares_reaches_the_normal_equations_solution():
    A, b = _data()
    normal, value = _linear(A, b)
    n = A.shape[1]
    lo, hi, dof = -10 * np.ones(n), 10 * np.ones(n), A.shape[0] - n
    exact = np.linalg.solve(A.T @ A, A.T @ b)
    res = levenberg_marquardt(normal, value, np.zeros(n), lo, hi, dof, max_iter=100, tol=1e-12)
    assert res.success and res.status.startswith("Stationary")
    assert np.allclose(res.z, exact, atol=1e-8)
    # the default stop: the remaining step is below 0.1 standard error, in the metric
    # (z - z*)^T A^T A (z - z*) = the Gauss-Newton decrement of 2 f for a linear r
    res = levenberg_marquardt(normal, value, np.zeros(n), lo, hi, dof, max_iter=100)
    d = res.z - exact
    s2 = float(np.sum((A @ exact - b) ** 2)) / dof
    assert res.success and 0 < d @ A.T @ A @ d <= 0.01 * s2 * (1 + 1e-6)


def test_active_bounds_give_the_bounded_least_squares_solution():
    A, b = _data(seed=1)
    normal, value = _linear(A, b)
    n = A.shape[1]
    lo, hi = -0.1 * np.ones(n), 0.1 * np.ones(n)
    res = levenberg_marquardt(normal, value, np.zeros(n), lo, hi, A.shape[0] - n, max_iter=200,
                              tol=1e-12)
    ref = lsq_linear(A, b, bounds=(lo, hi), tol=1e-12).x
    assert np.any(np.isclose(ref, lo) | np.isclose(ref, hi))  # the bounds do bind
    assert res.success and np.allclose(res.z, ref, atol=1e-7)


def test_a_linear_equality_constraint_gives_the_kkt_solution():
    A, b = _data(seed=2)
    normal, value = _linear(A, b)
    n = A.shape[1]
    G, h = np.ones((1, n)), np.array([0.25])
    K = np.block([[A.T @ A, G.T], [G, np.zeros((1, 1))]])
    exact = np.linalg.solve(K, np.concatenate([A.T @ b, h]))[:n]
    res = levenberg_marquardt(normal, value, np.zeros(n), -10 * np.ones(n), 10 * np.ones(n),
                              A.shape[0] - n, max_iter=100, G=G, h=h, tol=1e-12)
    assert res.success and np.allclose(res.z, exact, atol=1e-8)
    assert G @ res.z == pytest.approx(h, abs=1e-12)


def test_a_nonlinear_fit_reaches_scipys_optimum():
    # y = a exp(-b t) + c with 1 % noise: the optimum of an independent solver (MINPACK)
    rng = np.random.default_rng(5)
    t = np.linspace(0, 4, 50)
    y = 2.0 * np.exp(-1.3 * t) + 0.5 + 0.01 * rng.standard_normal(t.size)

    def r_of(z):
        return z[0] * np.exp(-z[1] * t) + z[2] - y

    def normal(z):
        r, e = r_of(z), np.exp(-z[1] * t)
        J = np.column_stack([e, -z[0] * t * e, np.ones_like(t)])
        return 0.5 * float(r @ r), J.T @ r, J.T @ J

    ref = least_squares(r_of, [1.0, 0.5, 0.0], method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    res = levenberg_marquardt(normal, lambda z: 0.5 * float(r_of(z) @ r_of(z)),
                              np.array([1.0, 0.5, 0.0]), -10 * np.ones(3), 10 * np.ones(3),
                              t.size - 3, max_iter=200, tol=1e-12)
    assert res.success and np.allclose(res.z, ref, atol=1e-8)


def test_an_undetermined_direction_keeps_its_start_and_the_rest_is_solved():
    # two nearly equal columns: a change of z1 - z2 moves the residuals by eps per unit,
    # far below the noise, so only z1 + z2 (and z3) are determined
    rng = np.random.default_rng(3)
    m, eps = 80, 1e-6
    a, c = rng.standard_normal(m), rng.standard_normal(m)
    A = np.column_stack([a, a + eps * rng.standard_normal(m), c])
    b = A @ np.array([0.2, 0.1, -0.3]) + 0.01 * rng.standard_normal(m)
    normal, value = _linear(A, b)
    z0 = np.array([0.4, -0.2, 0.0])
    lo, hi = -10 * np.ones(3), 10 * np.ones(3)
    res = levenberg_marquardt(normal, value, z0, lo, hi, m - 3, max_iter=100, tol=1e-12)
    # closed form: one Gauss-Newton step from z0 restricted to the determined directions
    f0, g0, H = normal(z0)
    B, lam = determined_directions(z0, g0, H, lo, hi, None, 2 * f0 / (m - 3))
    assert lam.size == 2
    exact = z0 - B @ ((B.T @ g0) / lam)
    assert res.success and np.allclose(res.z, exact, atol=1e-8)
    assert res.z[0] - res.z[1] == pytest.approx(z0[0] - z0[1], abs=1e-6)


def test_the_chunked_normal_equations_equal_the_dense_ones(tmp_path, monkeypatch):
    fr = tall_frame(32, seed=0, points_per_storey=12)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(case_dict(fr), sort_keys=False))
    monkeypatch.setattr(sparse, "CHUNK_MIN", 50)    # several chunks of frequencies
    monkeypatch.setattr(sparse, "CHUNK_BYTES", 1)
    problem = build_problem(assemble(load_case(str(tmp_path / "case.yaml")))).prefit
    ev = problem.evaluator
    assert ev.banded and len(ev._chunks(problem.target.omega.size, 8)) > 3
    z = problem.z0 + 0.05 * np.random.default_rng(4).standard_normal(problem.z0.size)
    r, J = problem.residuals(z)
    f, g, H = problem.normal_equations(z)
    assert f == pytest.approx(0.5 * float(r @ r), rel=1e-14)
    assert np.allclose(g, J.T @ r, rtol=0, atol=1e-12 * np.abs(J.T @ r).max())
    assert np.allclose(H, J.T @ J, rtol=0, atol=1e-12 * np.abs(J.T @ J).max())


@pytest.mark.parametrize("local", [False, True])
def test_lm_prefit_and_local_solves_reach_the_noise_floor_of_a_tall_frame(tmp_path, monkeypatch,
                                                                           local):
    fr = tall_frame(16, seed=0)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(case_dict(fr), sort_keys=False))
    monkeypatch.setattr(UpdatingProblem, "lm_prefit", True)
    monkeypatch.setattr(UpdatingProblem, "lm_local", local)
    case = assemble(load_case(str(tmp_path / "case.yaml")))
    problem = build_problem(case)
    res = problem.solve()
    assert res.success and res.prefit_iterations > 0
    assert res.status.startswith("Stationary (Levenberg") == local
    # ln|H (1 + noise e)| = ln|H| + noise Re(e) to first order: variance noise^2 / 2 per point
    assert res.f < 1.3 * 0.5 * problem.n_used * fr.noise ** 2 / 2
    k = np.array([p.nominal * (1 + t) for p, t in zip(case.params.params, problem.theta(res.z))
                  if p.group == "stiffness"])
    assert np.max(np.abs(k / fr.k - 1)) < 0.01


def test_lm_is_the_default_above_lm_from_free_variables_on_the_numeric_backends(tmp_path,
                                                                                 monkeypatch):
    """The package's default (None): LM local solves and prefits once the free variables
    exceed LM_FROM, IPOPT below; an explicit setting wins either way."""
    import nlp.solve.lm as L
    fr = tall_frame(16, seed=0, points_per_storey=12)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(case_dict(fr), sort_keys=False))
    problem = build_problem(assemble(load_case(str(tmp_path / "case.yaml"))))
    assert problem.backend != "dense" and problem.lm_local is None
    n_z = problem.params.n_z                      # 33
    monkeypatch.setattr(L, "LM_FROM", n_z)
    assert not problem.uses_lm
    monkeypatch.setattr(L, "LM_FROM", n_z - 1)
    assert problem.uses_lm
    res = problem.solve()
    assert res.status.startswith("Stationary (Levenberg") and res.prefit_iterations > 0
    monkeypatch.setattr(problem, "lm_local", False)
    assert not problem.uses_lm
