"""The scale null space of base-excitation FRFs; Gauss-Newton standard errors."""

import numpy as np
import pytest

from helpers_case import force_frf, write_case
from nlp.case import assemble, build_problem
from nlp.config import load_case
from nlp.errors import InputError
from nlp.identify import jacobian_report, standard_errors


def test_unanchored_ground_case_is_refused_with_explanation(tmp_path):
    path, _ = write_case(str(tmp_path), parameters={"fixed": None})
    with pytest.raises(InputError) as ei:
        assemble(load_case(path))
    msg = str(ei.value)
    assert "same factor" in msg and "fixed" in msg and "total_mass" in msg


def test_null_space_is_real_and_seen_by_the_jacobian(tmp_path):
    """Scaling M, C, K together leaves the FRFs unchanged (independent check),
    and the SVD of the all-free Jacobian shows the direction."""
    from make_four_story import MASSES, STIFFNESSES, true_damping
    from nlp.frf import frf_dynamic_stiffness
    from conftest import shear_K
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


def test_force_input_has_no_null_space(tmp_path):
    f, H, chans = force_frf("receptance")
    path, _ = write_case(str(tmp_path), H=H, f=f, parameters={"fixed": None},
                         excitation={"type": "force", "floor": 1},
                         data={"file": "frf.npz", "channels": chans})
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
