"""A whole diagnosis of two tests of one structure fitted jointly (data.tests)."""

import math

import numpy as np
import pytest
import yaml

from support.diagnosis import F, frame_matrices, write_frf
from nlp.case.load import load_case
from nlp.diagnosis.driver import diagnose
from nlp.testing.frames import shear_K


def _accelerance(M, C, K, floor, rng, noise=0.01):
    H = np.array([-(2 * np.pi * f) ** 2 * np.linalg.solve(
        K - (2 * np.pi * f) ** 2 * M + 2j * np.pi * f * C, np.eye(3)[floor - 1]) for f in F]).T
    return H * (1 + noise * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))


@pytest.mark.slow  # one joint diagnosis and the two tests refitted alone: about 1-2 min
def test_joint_diagnosis_names_one_coupling_and_one_gain_for_both_tests(tmp_path):
    """A 1-3 coupling of 900 N/m and a floor-2 accelerometer reading 12 % low, tested with the
    shaker at floor 1 and at floor 2: the joint diagnosis names both, each within 3 standard
    errors of the truth, with one gain for sensor a2 in both tests; every test alone either
    agrees or says why not."""
    rng = np.random.default_rng(11)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    e = np.array([1.0, 0.0, -1.0])
    K = shear_K(k) + 900.0 * np.outer(e, e)
    gain = np.array([1.0, 0.88, 1.0])[:, None]
    for name, floor in (("test1.npz", 1), ("test2.npz", 2)):
        write_frf(tmp_path, name, gain * _accelerance(M, C, K, floor, rng))
    case = {"name": "joint", "model": {"type": "shear_frame", "masses": m.tolist(),
                                       "stiffnesses": k.tolist()},
            "parameters": {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
            "damping": {"model": "rayleigh", "zeta": 0.015},
            "excitation": {"type": "force", "floor": 1},
            "data": {"file": "test1.npz", "tests": [{"file": "test2.npz", "force_floor": 2}],
                     "channels": [{"name": f"a{i + 1}", "floor": i + 1, "output": "accelerance",
                                   "column": i} for i in range(3)]},
            "frequencies": {"method": "half_power", "k": 2.0, "fmin": 0.5, "fmax": 15.0},
            "search": {"starts": 8, "seed": 0, "workers": 1}}
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(case, sort_keys=False))
    res = diagnose(load_case(str(tmp_path / "case.yaml")), str(tmp_path / "out"),
                   log=lambda *_: None)
    found = {f["physics"]: f for f in res["findings"] if "uncertainty" in f}
    assert set(found) == {"nonadjacent_coupling", "sensor_gain"}, res["summary"]
    kc = found["nonadjacent_coupling"]
    assert kc["location"] == {"between": [1, 3]}
    assert abs(kc["parameters"]["k13"] - 900.0) < 3 * kc["uncertainty"]["k13"] + 30
    g = found["sensor_gain"]
    assert g["location"] == {"channel": "a2"}     # the sensor, not a channel of one test
    assert abs(g["parameters"]["gain_a2"] + 0.12) < 3 * g["uncertainty"]["gain_a2"] + 0.005
    for f in found.values():
        # the correlation factor divides the scaled drop; the BIC price is unchanged
        e = f["evidence"]
        price = e["delta_bic"] - e["raw_delta_chi2"] / e["phi"]
        assert e["correlation_factor"] > 0
        assert math.isclose(e["delta_bic_correlated"], e["raw_delta_chi2"] / (
            e["phi"] * e["correlation_factor"]) + price, rel_tol=1e-9, abs_tol=1e-6)
    alone = res["tests_alone"]
    assert sorted({r["test"] for r in alone}) == ["test1", "test2"]
    assert len(alone) == 4 and all(r["agrees"] or r["reason"] for r in alone)
    coupling_t1 = next(r for r in alone if r["test"] == "test1"
                       and r["physics"] == "nonadjacent_coupling")
    assert coupling_t1["agrees"], coupling_t1
    assert math.isfinite(coupling_t1["delta_bic_alone"])
