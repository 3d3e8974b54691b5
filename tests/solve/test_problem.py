"""The NLP: derivatives, recovery of a known model, both solvers."""


import numpy as np
import pytest

from support.cases import force_frf, write_case
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case


def _problem(tmp_path, **kw):
    path, truth = write_case(str(tmp_path), **kw)
    case = assemble(load_case(path))
    return case, build_problem(case), truth


def _errors(case, problem, z, truth):
    M, K, C = problem.matrices(z)
    theta = problem.theta(z)
    k = case.model.alpha_nominal * (1 + theta[:4])
    m_err = np.abs(np.diag(M) / truth["masses"] - 1).max()
    k_err = np.abs(k / truth["stiffnesses"] - 1).max()
    Ct = np.array(truth["C"])
    return m_err, k_err, np.linalg.norm(C - Ct) / np.linalg.norm(Ct)


@pytest.mark.parametrize("residual", ["log_magnitude", "magnitude", "complex"])
def test_jacobian_and_gradient_match_finite_differences(tmp_path, residual):
    case, pr, _ = _problem(tmp_path, noise=0.02, objective={"residual": residual})
    rng = np.random.default_rng(1)
    z = pr.z0 + 0.05 * rng.standard_normal(pr.params.n_z)
    r, J = pr.residuals(z)
    h = 1e-6
    J_fd = np.empty_like(J)
    for j in range(z.size):
        e = np.zeros_like(z)
        e[j] = h
        J_fd[:, j] = (pr.residuals(z + e)[0] - pr.residuals(z - e)[0]) / (2 * h)
    assert np.abs(J - J_fd).max() <= 1e-6 * max(1.0, np.abs(J).max())
    g = J.T @ r
    g_fd = np.array([(pr.objective(z + h * e) - pr.objective(z - h * e)) / (2 * h)
                     for e in np.eye(z.size)])
    np.testing.assert_allclose(g, g_fd, rtol=1e-5, atol=1e-7 * np.abs(g).max())
    assert np.isclose(pr.objective(z), 0.5 * r @ r, rtol=1e-12)


def test_noise_free_recovers_every_parameter(tmp_path):
    case, pr, truth = _problem(tmp_path, noise=0.0)
    res = pr.solve()  # from Table 1's initial row
    assert res.success, res.status
    m_err, k_err, c_err = _errors(case, pr, res.z, truth)
    assert m_err < 1e-3 and k_err < 1e-3 and c_err < 1e-3, (m_err, k_err, c_err)


@pytest.mark.parametrize("solver", ["ipopt", "sqpmethod"])
def test_two_percent_noise_within_two_percent(tmp_path, solver):
    case, pr, truth = _problem(tmp_path, noise=0.02, seed=3,
                               solver={"name": solver, "options": {}})
    res = pr.solve()
    assert res.success, res.status
    m_err, k_err, _ = _errors(case, pr, res.z, truth)
    assert m_err < 0.02 and k_err < 0.02, (m_err, k_err)


def test_total_mass_anchor(tmp_path):
    total = 5.16 + 5.15 + 4.94 + 5.14
    case, pr, truth = _problem(tmp_path, noise=0.0, parameters={"fixed": None, "total_mass": total})
    res = pr.solve()
    assert res.success, res.status
    M, _, _ = pr.matrices(res.z)
    assert abs(np.trace(M) - total) < 1e-6
    m_err, k_err, c_err = _errors(case, pr, res.z, truth)
    assert m_err < 1e-3 and k_err < 1e-3 and c_err < 1e-3


def test_force_input_recovers_all_masses_without_anchor(tmp_path):
    f, H, chans = force_frf("accelerance")
    case, pr, truth = _problem(tmp_path, H=H, f=f, parameters={"fixed": None},
                               excitation={"type": "force", "floor": 1},
                               data={"file": "frf.npz", "window": "none", "channels": chans})
    res = pr.solve()
    m_err, k_err, c_err = _errors(case, pr, res.z, truth)
    assert m_err < 1e-3 and k_err < 1e-3, (m_err, k_err)


def test_uncompiled_path_gives_the_same_numbers(tmp_path):
    case, pr, _ = _problem(tmp_path / "c", noise=0.02)
    _, pr_vm, _ = _problem(tmp_path / "v", noise=0.02, solver={"name": "ipopt", "compile": False})
    assert pr.compiled and not pr_vm.compiled
    z = pr.z0 + 0.01
    np.testing.assert_allclose(pr.residuals(z)[1], pr_vm.residuals(z)[1], rtol=1e-10, atol=1e-12)
    a, b = pr.solve(), pr_vm.solve()
    np.testing.assert_allclose(a.z, b.z, rtol=1e-6, atol=1e-8)


def test_stationarity_is_the_residual_seen_by_the_jacobian(tmp_path):
    """The Gauss-Newton decrement g^T (J^T J)^-1 g equals |Q^T r|^2, the part of the
    residual that the Jacobian's columns can reach (Q: orthonormal basis of range J), at
    an interior point without constraints. A solve ends stationary: below STATIONARY."""
    from nlp.solve.stopping import STATIONARY
    case, pr, _ = _problem(tmp_path, noise=0.02)
    assert pr.constraint_jacobian().shape[0] == 0
    z = pr.z0 + 0.05 * np.random.default_rng(2).standard_normal(pr.params.n_z)
    r, J = pr.residuals(z)
    Q = np.linalg.qr(J)[0]
    assert pr.gn_decrement(z) == pytest.approx(float(np.sum((Q.T @ r) ** 2)), rel=1e-6)
    res = pr.solve()
    assert res.success and pr.gn_decrement(res.z) < STATIONARY
