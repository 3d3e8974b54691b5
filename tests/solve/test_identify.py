"""The scale null space of base-excitation FRFs; Gauss-Newton standard errors."""

import numpy as np
import pytest

from support.cases import force_frf, write_case
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.errors import InputError
from nlp.solve.identify import jacobian_report, standard_errors
from nlp.testing.four_story import MASSES, STIFFNESSES, true_damping
from support.frames import shear_K


def test_unanchored_ground_case_is_refused_with_explanation(tmp_path):
    path, _ = write_case(str(tmp_path), parameters={"fixed": None})
    with pytest.raises(InputError) as ei:
        assemble(load_case(path))
    msg = str(ei.value)
    assert "same factor" in msg and "fixed" in msg and "total_mass" in msg


def test_null_space_is_real_and_seen_by_the_jacobian(tmp_path):
    """Scaling M, C, K together leaves the FRFs unchanged (independent check),
    and the SVD of the all-free Jacobian shows the direction."""
    from nlp.frf.reference import frf_dynamic_stiffness
    M, K = np.diag(MASSES), shear_K(STIFFNESSES)
    C = true_damping(M, K)
    w = np.linspace(1, 40, 50)
    H1 = frf_dynamic_stiffness(M, C, K, w)
    H2 = frf_dynamic_stiffness(1.7 * M, 1.7 * C, 1.7 * K, w)
    np.testing.assert_allclose(H1, H2, rtol=1e-12)
    # anchored problem, then free m1 by building the Jacobian of all-free parameters
    path, _ = write_case(str(tmp_path), parameters={"fixed": None},
                         excitation={"type": "ground"})
    cfg = load_case(path, {})
    import dataclasses
    cfg = dataclasses.replace(cfg, parameters=dataclasses.replace(cfg.parameters, total_mass=20.0))
    pr = build_problem(assemble(cfg))  # total mass anchors the NLP; the residual J has the null space
    _, J = pr.residuals(pr.z0)
    rep = jacobian_report(J, pr.params.z_names, rtol=1e-6)
    assert rep["weak_directions"], rep["singular_values"][-3:]
    names = rep["weak_directions"][0]["combination"]
    assert any(n.startswith("k") for n in names) and any(n.startswith("m") for n in names)
    # on the anchor's surface the direction is gone, and the covariance is bounded
    from nlp.solve.identify import gauss_newton_covariance
    G = pr.constraint_jacobian()
    assert G.shape == (1, pr.params.n_z)
    assert not jacobian_report(J, pr.params.z_names, rtol=1e-6, G=G)["weak_directions"]
    # free, J^T J is singular (the scale direction); on the anchor's surface it is not,
    # and the covariance is that of coordinates N on the surface, N (N^T J^T J N)^-1 N^T
    from scipy.linalg import null_space
    sv = np.linalg.svd(J, compute_uv=False)
    assert sv[-1] < 1e-9 * sv[0]
    N = null_space(G)
    A = N.T @ J.T @ J @ N
    assert np.linalg.cond(A) < 1e9
    ref = N @ np.linalg.solve(A, N.T)
    cov = gauss_newton_covariance(J, G)
    np.testing.assert_allclose(cov, ref, rtol=1e-6, atol=1e-9 * np.abs(ref).max())


def test_force_input_has_no_null_space(tmp_path):
    f, H, chans = force_frf("receptance")
    path, _ = write_case(str(tmp_path), H=H, f=f, parameters={"fixed": None},
                         excitation={"type": "force", "floor": 1},
                         data={"file": "frf.npz", "window": "none", "channels": chans})
    pr = build_problem(assemble(load_case(path)))
    _, J = pr.residuals(pr.z0)
    assert not jacobian_report(J, pr.params.z_names, rtol=1e-6)["weak_directions"]


def test_standard_errors_match_monte_carlo():
    """For a linear model the Gauss-Newton errors are exact: compare with repeats."""
    rng = np.random.default_rng(0)
    A = rng.standard_normal((60, 3))
    x_true = np.array([1.0, -2.0, 0.5])
    sigma = 0.1
    est = []
    for _ in range(3000):
        y = A @ x_true + sigma * rng.standard_normal(60)
        est.append(np.linalg.lstsq(A, y, rcond=None)[0])
    y = A @ x_true + sigma * rng.standard_normal(60)
    x = np.linalg.lstsq(A, y, rcond=None)[0]
    cov, s2, dof = standard_errors(A, A @ x - y, 60)
    assert dof == 57 and abs(np.sqrt(s2) / sigma - 1) < 0.25
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.std(est, axis=0), rtol=0.3)


def test_standard_errors_on_the_anchor_surface_match_monte_carlo():
    """A null direction of J fixed only by an equality constraint (the total-mass
    anchor of a base-excited frame): the errors must be those of the constrained
    estimate, found here by solving the KKT system on repeated noisy data."""
    from nlp.solve.identify import jacobian_report
    rng = np.random.default_rng(1)
    A = rng.standard_normal((80, 4))
    null = np.array([1.0, 1.0, -1.0, 0.5])
    A -= np.outer(A @ null, null) / (null @ null)  # A null = 0: the scale direction
    G = np.array([[1.0, 2.0, 0.0, 1.0]])           # the anchor, G x = g0
    x_true = np.array([0.3, -0.2, 0.1, 0.4])
    g0 = G @ x_true
    sigma = 0.05
    K = np.block([[A.T @ A, G.T], [G, np.zeros((1, 1))]])

    def fit(y):
        return np.linalg.solve(K, np.concatenate([A.T @ y, g0]))[:4]

    est = np.array([fit(A @ x_true + sigma * rng.standard_normal(80)) for _ in range(3000)])
    y = A @ x_true + sigma * rng.standard_normal(80)
    x = fit(y)
    cov, s2, dof = standard_errors(A, A @ x - y, 80, G)
    assert dof == 77
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.std(est, axis=0), rtol=0.3)
    # without the constraint the null direction makes the errors meaningless
    cov_free, _, _ = standard_errors(A, A @ x - y, 80)
    assert not np.allclose(np.sqrt(np.diag(cov_free)), np.std(est, axis=0), rtol=0.3)
    # and the anchored direction is not reported as weak
    assert jacobian_report(A, list("abcd"), G=G)["weak_directions"] == []
    assert jacobian_report(A, list("abcd"))["weak_directions"]

