"""The joints' distortion of a one-segment sweep (nlp.diagnosis.sweep), checked against an
independent simulation of a 3-storey frame with cubic story springs (fixed-step RK4 here,
not the package's FRF code), against finite differences, and in a diagnosis.
"""

import json
import os

import numpy as np
import pytest

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.driver import diagnose
from nlp.diagnosis.sweep import (ITERATIONS, distortion, distortion_basis, response_setup,
                                 story_patterns)
from nlp.testing.noise_sim import add_noise, chirp_input, frame, records_case

FS_FINE, DECIM = 500.0, 5
CHANGE = np.array([-0.010, 0.008, -0.012])   # 24 k3 Var(d) / k per story (level to 3x)
STIFF = np.array([4000.0, 3200.0, 2600.0])   # nlp.testing.noise_sim's frame
K13 = 500.0                                  # [N/m], a coupling of floors 1 and 3


def _rk4(x, M, C, K, k3):
    """Absolute floor accelerations of M q'' + C q' + K q + f(q) = -M 1 a_g, f the cubic
    story springs k3 d^3 (d = q_s - q_{s-1}); a_g linear between samples."""
    n, h = M.shape[0], 1.0 / FS_FINE
    Mi, r = np.linalg.inv(M), np.ones(n)

    def acc(q, v, ag):
        d = np.diff(np.concatenate([[0.0], q]))
        s = k3 * d ** 3
        f = s - np.concatenate([s[1:], [0.0]])
        return Mi @ (-C @ v - K @ q - f) - r * ag

    q, v = np.zeros(n), np.zeros(n)
    out = np.empty((n, x.size))
    for i in range(x.size):
        a0 = acc(q, v, x[i])
        out[:, i] = a0 + x[i]
        if i + 1 == x.size:
            break
        xm = 0.5 * (x[i] + x[i + 1])
        k1q, k1v = v, a0
        k2q, k2v = v + 0.5 * h * k1v, acc(q + 0.5 * h * k1q, v + 0.5 * h * k1v, xm)
        k3q, k3v = v + 0.5 * h * k2v, acc(q + 0.5 * h * k2q, v + 0.5 * h * k2v, xm)
        k4q, k4v = v + h * k3v, acc(q + h * k3q, v + h * k3v, x[i + 1])
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
    return out


def _drift_var(x, M, C, K):
    """Each story's linear drift variance while the chirp drives (by the same RK4)."""
    n, h = M.shape[0], 1.0 / FS_FINE
    # the linear response's drifts from its accelerations: integrate relative motion
    a_rel = _rk4(x, M, C, K, np.zeros(n)) - x[None, :]
    v = np.cumsum(a_rel, axis=1) * h
    q = np.cumsum(v, axis=1) * h
    d = np.diff(np.vstack([np.zeros(x.size), q]), axis=0)
    on = np.abs(x) > 0
    return d[:, on].var(axis=1)


@pytest.fixture(scope="module")
def sweep_cases(tmp_path_factory):
    """Noise-free and noisy records of the frame with and without cubic joints, one chirp."""
    M, C, K = frame()
    x = chirp_input(FS_FINE, 0.5, 12.0, 60.0, 5.0, 15.0)
    k3 = CHANGE * STIFF / (24 * _drift_var(x, M, C, K))
    lin, nl = _rk4(x, M, C, K, np.zeros(3)), _rk4(x, M, C, K, k3)
    extra = {"nperseg": "all", "window": "boxcar", "estimator": "H1"}
    freq = {"fmin": 0.7, "fmax": 11.0}
    paths = {}
    for name, y in (("lin", lin), ("nl", nl)):
        folder = tmp_path_factory.mktemp(name)
        paths[name] = records_case(folder, x[::DECIM], y[:, ::DECIM], extra, freq)
    Kc = K.copy()   # a coupling between floors 1 and 3 (nonadjacent_coupling)
    Kc[np.ix_([0, 2], [0, 2])] += K13 * np.array([[1.0, -1.0], [-1.0, 1.0]])
    coupled = _rk4(x, M, C, Kc, k3)
    for name, y in (("lin_noisy", lin), ("nl_noisy", nl), ("coupled_noisy", coupled)):
        folder = tmp_path_factory.mktemp(name)
        xn, yn = add_noise(x[::DECIM], y[:, ::DECIM], 0.01, np.random.default_rng(7))
        paths[name] = records_case(folder, xn, yn, extra, freq)
    return {"paths": paths, "k3": k3, "mats": (M, C, K)}


def _setup(path, mats):
    case = assemble(load_case(path))
    _, B = story_patterns(case.model, 3)
    return case, response_setup(*mats, B, case)


def test_the_distortion_is_the_difference_between_the_nonlinear_and_linear_records(sweep_cases):
    case_nl, pre = _setup(sweep_cases["paths"]["nl"], sweep_cases["mats"])
    case_lin = assemble(load_case(sweep_cases["paths"]["lin"]))
    band = (case_nl.f > 0.7) & (case_nl.f < 11.0)
    measured = np.log(np.abs(case_nl.H / case_lin.H))[:, band]
    a = np.abs(measured)
    assert a.max() > 0.2          # the joints bend the records' peaks by tens of per cent
    err = {it: np.abs(measured - distortion(pre, sweep_cases["k3"], it).real[:, band])
           for it in (0, ITERATIONS)}
    # the series fed back: 95 % of the bins within a tenth of their distortion; a few bins
    # where |distortion| nears 1 (a response crossing zero) are beyond any series
    assert np.mean(err[ITERATIONS] < 0.1 * a + 1e-4) > 0.9
    assert np.quantile(err[ITERATIONS], 0.9) < 0.02 * np.quantile(a, 0.9)
    # first order alone is ten times further off (why the forces' response is fed back)
    assert np.quantile(err[0], 0.9) > 10 * np.quantile(err[ITERATIONS], 0.9)


def test_the_first_order_basis_is_the_derivative_of_the_distortion(sweep_cases):
    case, pre = _setup(sweep_cases["paths"]["nl"], sweep_cases["mats"])
    band = (case.f > 0.7) & (case.f < 11.0)
    ratio = distortion_basis(pre)
    for s in range(3):
        h = 1e-4 * abs(sweep_cases["k3"][s])
        e = np.zeros(3)
        e[s] = h
        fd = (distortion(pre, e) - distortion(pre, -e)) / (2 * h)
        assert np.allclose(fd[:, band], ratio[s][:, band], rtol=1e-4,
                           atol=1e-6 * np.abs(ratio[s][:, band]).max())


def test_a_frame_with_joints_is_adequate_once_their_bend_is_divided_out(sweep_cases, tmp_path):
    out = str(tmp_path / "nl")
    res = diagnose(load_case(sweep_cases["paths"]["nl_noisy"]), out, log=lambda *a, **k: None)
    sw = res["sweep_joints"]
    assert res["verdict"] == "adequate"
    assert sw and sw["accepted"]
    assert np.allclose(sw["change"], CHANGE, atol=0.002)
    before, after = sw["reduced_chi2"]
    assert before > 3 * after and after < 1.5
    assert json.load(open(os.path.join(out, "diagnosis.json")))["sweep_joints"]["accepted"]


def test_a_linear_frame_is_left_as_measured(sweep_cases, tmp_path):
    res = diagnose(load_case(sweep_cases["paths"]["lin_noisy"]), str(tmp_path / "lin"),
                   log=lambda *a, **k: None)
    assert res["verdict"] == "adequate"
    assert not res["sweep_joints"]


def test_joints_are_divided_out_beside_a_finding(sweep_cases, tmp_path):
    res = diagnose(load_case(sweep_cases["paths"]["coupled_noisy"]), str(tmp_path / "c"),
                   log=lambda *a, **k: None)
    found = [(f["physics"], f["location"]) for f in res["findings"]]
    assert found == [("nonadjacent_coupling", {"between": [1, 3]})]
    assert res["verdict"] == "missing_physics"
    # the coupling's misfit is most of the baseline's: the bend is divided out only once the
    # coupling is in the model, and its k3 are the planted ones
    sw = res["sweep_joints"]
    assert sw["accepted"] and sw["confirmed"] and sw["after_findings"]
    assert np.allclose(sw["k3"], sweep_cases["k3"], rtol=0.15)
    assert res["fit"]["after"]["reduced_chi2"] < 1.5
