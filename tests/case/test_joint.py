"""Several tests of one structure fitted jointly (data.tests, nlp.case.joint): each stacked
channel is driven where its own test was driven, and one sensor keeps one gain in every
test. Checked against a direct numpy solve of the truth model."""

import os

import numpy as np
import pytest
import yaml

from support.cases import BASE, deep_update
from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.families import SensorGain
from nlp.errors import InputError
from nlp.diagnosis.fitting import diagnosis_problem, fit_target, noise_sigma, quasi_se
from nlp.diagnosis.joint import alone_fits
from nlp.testing.four_story import MASSES, STIFFNESSES, true_damping
from nlp.testing.frames import shear_K

F = np.arange(0.02, 8, 0.02)


def _accelerance(drive, gains=(1, 1, 1, 1), noise=0.0, seed=0):
    """Truth-model accelerances of the four floors to a force at floor `drive` (1-based),
    each sensor's gain applied, with multiplicative log-normal noise."""
    M, K = np.diag(MASSES), shear_K(STIFFNESSES)
    C = true_damping(M, K)
    w = 2 * np.pi * F
    H = np.array([np.linalg.solve(K - wk**2 * M + 1j * wk * C, np.eye(4)[drive - 1])
                  for wk in w]).T * -(w**2)
    H = H * np.asarray(gains, float)[:, None]
    rng = np.random.default_rng(seed)
    return H * np.exp(noise * rng.standard_normal(H.shape))


NOMINAL = {"masses": [float(0.95 * m) for m in MASSES],
           "stiffnesses": [float(1.1 * k) for k in STIFFNESSES]}


def _joint_case(folder, gains=(1, 1, 1, 1), noise=0.0, gains2=None):
    """Two tests (force at floors 1 and 3); gains2: the second test's sensor gains, when
    they differ from the first's."""
    for name, drive, seed, g in (("t1.npz", 1, 1, gains), ("t2.npz", 3, 2, gains2 or gains)):
        np.savez(os.path.join(folder, name), f=F, H=_accelerance(drive, g, noise, seed))
    cfg = deep_update(BASE, {
        "model": {"type": "shear_frame", **NOMINAL},
        "excitation": {"type": "force", "floor": 1},
        "parameters": {"fixed": None},
        "frequencies": {"method": "half_power", "k": 2.0, "fmin": 0.5, "fmax": 6.5},
        "data": {"file": "t1.npz", "tests": [{"file": "t2.npz", "force_floor": 3}],
                 "channels": [{"name": f"a{i + 1}", "floor": i + 1, "output": "accelerance",
                               "column": i} for i in range(4)]}})
    path = os.path.join(folder, "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    return assemble(load_case(path))


def test_each_stacked_channel_is_driven_where_its_test_was(tmp_path):
    case = _joint_case(str(tmp_path))
    assert [ch.name for ch in case.channels] == ["a1", "a2", "a3", "a4",
                                                 "a1@t2", "a2@t2", "a3@t2", "a4@t2"]
    idx = case.selected
    pr = diagnosis_problem(case, fit_target(case, idx, noise_sigma(case, idx)), optimize=False)
    M, K, C = (np.array(x) for x in pr.matrices_fn(pr.z0))
    w = 2 * np.pi * case.f[idx]
    for drive, rows in ((0, range(4)), (2, range(4, 8))):
        X = np.array([np.linalg.solve(K - wk**2 * M + 1j * wk * C, np.eye(4)[drive])
                      for wk in w]).T * -(w**2)
        got = pr.channel_frfs(pr.z0, w)[list(rows)]
        np.testing.assert_allclose(got, X, rtol=1e-9)
    # the data of the second test are its own file's, on the shared grid
    np.testing.assert_allclose(case.H[4:], _accelerance(3), rtol=1e-12)


def test_one_sensor_gain_acts_on_that_sensor_in_every_test(tmp_path):
    case = _joint_case(str(tmp_path))
    idx = case.selected
    tg = fit_target(case, idx, noise_sigma(case, idx))
    pr = diagnosis_problem(case, tg, [SensorGain("a2")], values=[[0.07]], optimize=False)
    pr0 = diagnosis_problem(case, tg, optimize=False)
    w = 2 * np.pi * case.f[idx]
    ratio = pr.channel_frfs(pr.z0, w) / pr0.channel_frfs(pr0.z0, w)
    expected = np.ones(8)
    expected[[1, 5]] = 1.07       # a2 in the first test and a2@t2 in the second
    np.testing.assert_allclose(ratio, expected[:, None] * np.ones(idx.size), rtol=1e-9)


def test_the_joint_fit_recovers_a_gain_the_tests_share(tmp_path):
    """A 6 % gain on sensor a2 in both tests, 1 % noise: the joint fit with one gain finds it
    within 3 standard errors, and the stiffnesses (10 % off in the nominal) within 3 of
    theirs."""
    case = _joint_case(str(tmp_path), gains=(1, 1.06, 1, 1), noise=0.01)
    idx = case.selected
    tg = fit_target(case, idx, noise_sigma(case, idx))
    pr = diagnosis_problem(case, tg, [SensorGain("a2")], optimize=False)
    res = pr.solve(pr.z0)
    th, se = pr.theta(res.z), quasi_se(pr, res.z)[0]
    g = pr.params.names.index("gain_a2")
    assert abs(th[g] - 0.06) < 3 * se[g] and se[g] < 0.02, (th[g], se[g])
    names = pr.params.names
    for i in range(4):
        k = names.index(f"k{i + 1}")
        assert abs(th[k] - (1 / 1.1 - 1)) < 3 * se[k], (names[k], th[k], se[k])


@pytest.mark.parametrize("tests,key,words", [
    ([{"file": "missing.npz"}], "data.tests[0].file", "existing file"),
    ([{"file": "t2.npz", "force_floor": 0}], "data.tests[0].force_floor", "> 0"),
    ([{"file": "t2.npz", "label": "t1"}], "data.tests[0].label", "no other test"),
    ("t2.npz", "data.tests", "a list"),
    ([{"file": "t2.npz", "label": "second"}, "held-out"], "data.validation_file", "no held-out"),
])
def test_bad_joint_tests_are_named(tmp_path, tests, key, words):
    _joint_case(str(tmp_path))
    path = os.path.join(str(tmp_path), "case.yaml")
    with open(path) as fh:
        cfg = yaml.safe_load(fh)
    if isinstance(tests, list) and "held-out" in tests:
        tests, cfg["data"]["validation_file"] = tests[:-1], "t2.npz"
    cfg["data"]["tests"] = tests
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    with pytest.raises(InputError) as ei:
        assemble(load_case(path))
    assert f"'{key}'" in str(ei.value) and words in str(ei.value), str(ei.value)


def _alone(case, sensor):
    """The joint fit with a gain on sensor, then each test alone (alone_fits)."""
    idx = case.selected
    tg = fit_target(case, idx, noise_sigma(case, idx))
    e = SensorGain(sensor)
    pr = diagnosis_problem(case, tg, [e], optimize=False)
    res = pr.solve(pr.z0)
    th, se = pr.theta(res.z), quasi_se(pr, res.z)[0]
    g = pr.params.names.index(f"gain_{sensor}")
    found = [{"enrichment": e, "physics": e.family, "location": e.location,
              "parameters": {f"gain_{sensor}": float(th[g])},
              "uncertainty": {f"gain_{sensor}": float(se[g])}}]
    return alone_fits(case.config, case, case.f[idx], found, {"problem": pr, "z": res.z},
                      lambda s: None)


def test_each_test_alone_agrees_with_a_gain_they_share(tmp_path):
    """The 6 % gain on a2 in both tests, fitted jointly: refitted on each test alone, both
    find it (within 3 standard errors of 6 %) and agree with the joint estimate."""
    records = _alone(_joint_case(str(tmp_path), gains=(1, 1.06, 1, 1), noise=0.01), "a2")
    assert [r["test"] for r in records] == ["t1", "t2"]
    for r in records:
        assert r["agrees"], r
        assert abs(r["alone"]["gain_a2"] - 0.06) < 3 * r["alone_uncertainty"]["gain_a2"], r


def test_a_gain_of_one_test_only_is_reported_as_such(tmp_path):
    """Sensor a2 recalibrated between the tests (6 % off in the second only): the joint gain
    lies between; the first test alone cannot see a gain, the second sees its own 6 %."""
    case = _joint_case(str(tmp_path), gains=(1, 1, 1, 1), gains2=(1, 1.06, 1, 1), noise=0.01)
    first, second = _alone(case, "a2")
    assert not first["agrees"] and not second["agrees"]
    assert first["reason"].startswith("this test cannot see it"), first
    assert abs(first["alone"]["gain_a2"]) < 3 * first["alone_uncertainty"]["gain_a2"]
    assert second["reason"].startswith("test-specific"), second
    assert abs(second["alone"]["gain_a2"] - 0.06) < 3 * second["alone_uncertainty"]["gain_a2"]
