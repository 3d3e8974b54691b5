"""Every channel's calibration inside the case's tolerance, and gains named only beyond it.

The diagnoses run on 3-storey shake-table cases of nlp/testing/benchmark.py whose records
are then scaled channel by channel: the planted gains are the truth the fitted ones are
checked against (ground input, so each channel's FRF gain is its own scale exactly).
"""

import itertools
import os
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
import yaml

from nlp.case.load import load_case
from nlp.diagnosis.calibration import Calibration, calibration_of
from nlp.diagnosis.driver import diagnose
from nlp.errors import InputError
from nlp.output.report import write_report
from nlp.testing.benchmark import make_case


def test_bounds_are_the_extremes_of_a_ratio_of_two_transducers():
    t = 0.03
    e = np.linspace(-t, t, 61)
    ratios = [(1 + a) / (1 + b) - 1 for a, b in itertools.product(e, e)]
    lo, hi = Calibration(("a1",), t).bounds
    assert lo == pytest.approx(min(ratios), rel=1e-12)
    assert hi == pytest.approx(max(ratios), rel=1e-12)


def test_each_channel_is_scaled_by_its_own_gain_only():
    cal = Calibration(("a1", "a2"), 0.03)
    th = ca.DM([0.02, -0.01])
    for ch, g in (("a1", 0.02), ("a2", -0.01)):
        hr, hi = cal.output_on(ch, ca.DM(3.0), ca.DM(-4.0), ca.DM(10.0), th)
        assert float(hr) == pytest.approx(3.0 * (1 + g)) and float(hi) == pytest.approx(-4.0 * (1 + g))
    spec = Calibration(("a1", "a2"), 0.03, released=("a2",)).spec({})
    assert spec["upper"][0] == pytest.approx(1.03 / 0.97 - 1) and spec["upper"][1] == 1.0


def _stub(excitation, total_mass, tol=0.03):
    chans = tuple(SimpleNamespace(sensor_name=n) for n in ("a1", "a2", "a3"))
    cfg = SimpleNamespace(data=SimpleNamespace(calibration=tol),
                          parameters=SimpleNamespace(total_mass=total_mass))
    return SimpleNamespace(config=cfg, channels=chans, target=SimpleNamespace(excitation=excitation),
                           released_gains=())


def test_a_force_test_without_a_mass_anchor_leaves_the_common_gain_to_the_structure():
    # 1 / (1 + g_in) on every FRF of a force test is M, C, K scaled by (1 + g_in)
    assert calibration_of(_stub("force", None)).channels == ("a2", "a3")
    assert calibration_of(_stub("force", 15.0)).channels == ("a1", "a2", "a3")
    assert calibration_of(_stub("ground", None)).channels == ("a1", "a2", "a3")
    assert calibration_of(_stub("ground", None, tol=None)) is None


def _case(tmp_path, spec, gains, tol):
    folder = str(tmp_path / "case")
    make_case(folder, {"storeys": 3, "seconds": 600.0, "excitation": "ground", **spec}, 11)
    path = os.path.join(folder, "case.yaml")
    y = yaml.safe_load(open(path))
    y["data"]["calibration"] = tol
    yaml.safe_dump(y, open(path, "w"), sort_keys=False)
    rec = os.path.join(folder, y["data"]["file"])
    head = open(rec).readline().strip().split(",")
    data = np.loadtxt(rec, delimiter=",", skiprows=1)
    for ch, g in zip(y["data"]["channels"], gains):
        data[:, head.index(ch["column"])] *= 1 + g
    np.savetxt(rec, data, delimiter=",", header=",".join(head), comments="", fmt="%.10e")
    return path


def test_a_tolerance_that_is_not_a_fraction_is_refused(tmp_path):
    path = _case(tmp_path, {"family": None}, [], 0.7)
    with pytest.raises(InputError, match="data.calibration"):
        load_case(path)


@pytest.mark.parametrize("family,effect,truth", [
    (None, {}, None),
    ("added_mass", {"location": 2, "value": 1.5}, ("added_mass", {"floor": 2}, "dm2", 1.5))],
    ids=["null", "added_mass"])
def test_gains_inside_the_tolerance_are_fitted_not_named(tmp_path, family, effect, truth):
    planted = [0.025, -0.02, 0.015]
    res = diagnose(load_case(_case(tmp_path, {"family": family, **effect}, planted, 0.03)),
                   str(tmp_path / "out"), log=lambda *_: None)
    fitted = res["calibration"]["gains"]
    for ch, g in zip(("a1", "a2", "a3"), planted):
        assert abs(fitted[ch] - g) < 0.005, (ch, fitted)
    write_report(str(tmp_path / "out"))
    html = (tmp_path / "out" / "report.html").read_text()
    assert "<h2>Calibration</h2>" in html and html.count("inside the tolerance") == 3
    if truth is None:
        assert res["verdict"] == "adequate" and res["findings"] == []
        return
    fam, loc, name, value = truth
    assert [(f["physics"], f["location"]) for f in res["findings"]] == [(fam, loc)]
    assert res["findings"][0]["parameters"][name] == pytest.approx(value, rel=0.05)


def test_a_gain_beyond_the_tolerance_is_named(tmp_path):
    path = _case(tmp_path, {"family": "sensor_gain", "location": 2, "value": 0.3}, [], 0.03)
    res = diagnose(load_case(path), str(tmp_path / "out"), log=lambda *_: None)
    assert res["verdict"] == "setup_error"
    [f] = res["findings"]
    assert f["physics"] == "sensor_gain" and f["location"] == {"channel": "a2"}
    assert f["parameters"]["gain_a2"] == pytest.approx(0.3, abs=0.01)
    # "before" is the model with every gain inside the tolerance, which a 30 % gain defeats
    fit = res["fit"]
    assert fit["before"]["reduced_chi2"] > 5 * fit["after"]["reduced_chi2"], fit
    assert fit["after"]["reduced_chi2"] < 1.5
