"""General matrix models from files, tied parameters, Rayleigh damping."""

import os

import numpy as np
import pytest
import scipy.io
import yaml

from support.cases import write_case
from support.frames import TABLE1_INITIAL_K, TABLE1_INITIAL_M, shear_K
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.errors import InputError
from nlp.frf.reference import frf_dynamic_stiffness
from nlp.testing.four_story import MASSES, STIFFNESSES, true_damping


def _write_model(folder, ext):
    n = 4
    M_infl = np.array([np.diag(TABLE1_INITIAL_M[r] * np.eye(n)[r]) for r in range(n)])
    K_infl = np.array([shear_K(TABLE1_INITIAL_K * np.eye(n)[r]) for r in range(n)])
    arrays = dict(M0=np.diag(TABLE1_INITIAL_M), K0=shear_K(TABLE1_INITIAL_K), M_infl=M_infl,
                  K_infl=K_infl)
    path = os.path.join(folder, f"model.{ext}")
    if ext == "npz":
        np.savez(path, **arrays)
    else:
        scipy.io.savemat(path, arrays)
    return f"model.{ext}"


def test_matrix_model_from_npz_and_mat_recovers_truth(tmp_path):
    for ext in ("npz", "mat"):
        folder = str(tmp_path / ext)
        os.makedirs(folder)
        name = _write_model(folder, ext)
        path, truth = write_case(folder, model={"type": "matrices", "file": name,
                                                "masses": None, "stiffnesses": None},
                                 parameters={"fixed": None})
        with open(path) as fh:
            cfg = yaml.safe_load(fh)
        # a matrix group has no value in kg: a bare number (the old multiplier) is refused
        cfg["parameters"]["fixed"] = {"beta1": 5.16 / 4.64}
        with open(path, "w") as fh:
            yaml.safe_dump(cfg, fh)
        with pytest.raises(InputError, match=r"parameters.fixed.beta1.*multiplier"):
            assemble(load_case(path))
        cfg["parameters"]["fixed"] = {"beta1": {"multiplier": 5.16 / 4.64}}
        with open(path, "w") as fh:
            yaml.safe_dump(cfg, fh)
        case = assemble(load_case(path))
        assert case.params.params[case.params.names.index("beta1")].unit == "x nominal"
        pr = build_problem(case)
        res = pr.solve()
        M, K, C = pr.matrices(res.z)
        np.testing.assert_allclose(np.diag(M), truth["masses"], rtol=1e-3)
        np.testing.assert_allclose(K, shear_K(truth["stiffnesses"]), rtol=1e-3, atol=1e-6)


def test_tied_stiffnesses_share_one_variable(tmp_path):
    k = np.array([1054.98, 1300.0, 1300.0 * 1420 / 1217, 2738.17])  # k2, k3: same relative change
    M, K = np.diag(MASSES), shear_K(k)
    f = np.arange(0.02, 8, 0.02)
    H = frf_dynamic_stiffness(M, true_damping(M, K), K, 2 * np.pi * f)
    path, _ = write_case(str(tmp_path), H=H, f=f, parameters={"tie": {"k23": ["k2", "k3"]}})
    case = assemble(load_case(path))
    pr = build_problem(case)
    assert pr.params.n_z == 16 and "k2+k3" in pr.params.z_names
    theta = pr.theta(pr.solve().z)
    np.testing.assert_allclose(TABLE1_INITIAL_K * (1 + theta[:4]), k, rtol=1e-3)
    assert theta[1] == theta[2]


def test_rayleigh_damping_case_recovers_rayleigh_truth(tmp_path):
    M, K = np.diag(MASSES), shear_K(STIFFNESSES)
    a0, a1 = 0.12, 0.0018
    f = np.arange(0.02, 8, 0.02)
    H = frf_dynamic_stiffness(M, a0 * M + a1 * K, K, 2 * np.pi * f)
    path, _ = write_case(str(tmp_path), H=H, f=f, damping={"model": "rayleigh", "zeta": 0.02})
    pr = build_problem(assemble(load_case(path)))
    res = pr.solve()
    Mu, Ku, Cu = pr.matrices(res.z)
    np.testing.assert_allclose(Cu, a0 * M + a1 * K, rtol=1e-3, atol=1e-6)
    np.testing.assert_allclose(np.diag(Mu), MASSES, rtol=1e-3)


def test_shear_frame_values_in_kg_or_as_multiplier_mean_the_same(tmp_path):
    """parameters.fixed/initial/bounds: a bare number is kg or N/m; {multiplier: x} is
    x times the nominal value. Both forms give the same parameter."""
    a, _ = write_case(str(tmp_path / "a"), parameters={
        "fixed": {"m1": 5.16}, "initial": {"k2": 1300.0}, "bounds": {"k3": [710.0, 2840.0]}})
    b, _ = write_case(str(tmp_path / "b"), parameters={
        "fixed": {"m1": {"multiplier": 5.16 / 4.64}}, "initial": {"k2": {"multiplier": 1300 / 1217}},
        "bounds": {"k3": {"multiplier": [0.5, 2.0]}}})
    pa, pb = (assemble(load_case(p)).params for p in (a, b))
    for x, y in zip(pa.params, pb.params):
        assert (x.initial, x.lower, x.upper, x.fixed) == pytest.approx(
            (y.initial, y.lower, y.upper, y.fixed), rel=1e-12, abs=1e-12), x.name
    k3 = pa.params[pa.names.index("k3")]
    assert k3.nominal * (1 + k3.lower) == pytest.approx(710.0) and k3.unit == "N/m"
