"""A tall shear frame with one parameter per storey (issue 47): data from an independent
modal sum (nlp.testing.tall), every start prefitted on |H| before ln|H|."""

import json
import os

import numpy as np
import pytest
import yaml

import nlp
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.solve.identify import standard_errors
from nlp.testing.tall import NOISE, case_dict, tall_frame


def _write(tmp_path, n, **objective):
    fr = tall_frame(n, seed=0)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    doc = case_dict(fr)
    doc["objective"].update(objective)
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path), fr


def _stiffness(case, theta):
    return np.array([p.nominal * (1 + t) for p, t in zip(case.params.params, theta)
                     if p.group == "stiffness"])


def test_prefit_reaches_the_noise_floor_and_the_truth(tmp_path):
    path, fr = _write(tmp_path, 16)
    case = assemble(load_case(path))
    problem = build_problem(case)
    assert problem.prefit is not None and problem.prefit.residual == "complex"
    res = problem.solve()
    # ln|H (1 + noise e)| = ln|H| + noise Re(e) to first order: variance noise^2 / 2 per point
    f_floor = 0.5 * problem.n_used * NOISE ** 2 / 2
    assert res.success and res.f < 1.3 * f_floor
    r, J = problem.residuals(res.z)
    cov, _, _ = standard_errors(J, r, problem.n_used, problem.constraint_jacobian())
    T = case.params.T
    se = np.sqrt(np.diag(T @ cov @ T.T))
    ks = [i for i, p in enumerate(case.params.params) if p.group == "stiffness"]
    k_fit = _stiffness(case, problem.theta(res.z))
    k_se = np.array([case.params.params[i].nominal * se[i] for i in ks])
    assert np.max(np.abs(k_fit / fr.k - 1)) < 0.01
    assert np.max(np.abs(k_fit - fr.k) / k_se) < 4.5


@pytest.mark.slow
def test_a_local_minimum_is_flagged(tmp_path):
    # without the prefit the log-magnitude fit of this frame ends far above the noise
    path, _ = _write(tmp_path, 16, prefit="none")
    result = nlp.run(path, str(tmp_path / "out"), log=lambda m: None, starts=1)
    with open(os.path.join(result.out, "result.json")) as fh:
        doc = json.load(fh)
    kinds = {f["kind"]: f for f in doc["flags"]}
    assert "misfit_above_noise" in kinds and kinds["misfit_above_noise"]["ratio"] > 10


def test_every_floor_weighed_frees_only_the_stiffnesses(tmp_path):
    # masses known (fixed at the truth): n stiffnesses and the 2 Rayleigh coefficients
    n = 16
    fr = tall_frame(n, seed=0)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case_dict(fr, weighed="all"), sort_keys=False))
    case = assemble(load_case(str(path)))
    free = [p for p in case.params.params if not p.fixed]
    assert sorted({p.group for p in free}) == ["damping", "stiffness"] and len(free) == n + 2
    problem = build_problem(case)
    res = problem.solve()
    assert res.success
    m_fit = np.array([p.nominal * (1 + t) for p, t in zip(case.params.params, problem.theta(res.z))
                      if p.group == "mass"])
    assert np.allclose(m_fit, fr.m, rtol=1e-3)
    assert np.max(np.abs(_stiffness(case, problem.theta(res.z)) / fr.k - 1)) < 0.01


def test_a_receptance_at_every_floor_determines_masses_and_stiffnesses(tmp_path):
    # one point a storey at every floor: 2 n + 1 free parameters fitted to the truth
    n = 16
    fr = tall_frame(n, seed=0, sensors=n, points_per_storey=1)
    assert fr.dofs == list(range(n)) and fr.H.shape == (n, n)
    np.savez_compressed(tmp_path / "frf.npz", f=fr.f, H=fr.H)
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(case_dict(fr), sort_keys=False))
    case = assemble(load_case(str(path)))
    assert sum(not p.fixed for p in case.params.params) == 2 * n + 1
    problem = build_problem(case)
    res = problem.solve()
    assert res.success
    theta = problem.theta(res.z)
    m_fit = np.array([p.nominal * (1 + t) for p, t in zip(case.params.params, theta)
                      if p.group == "mass"])
    assert np.max(np.abs(m_fit / fr.m - 1)) < 0.01
    assert np.max(np.abs(_stiffness(case, theta) / fr.k - 1)) < 0.01
