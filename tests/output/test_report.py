"""report.html of a run and of a diagnosis, from hand-written result files: numbers shown as
the console shows them, the physical C, units in words, provenance; no backend switch."""

import json
import math
import re
import subprocess
import sys

import pytest

from nlp.diagnosis.verdict import log_conclusion
from nlp.output.report import fmt_percent, fmt_value, write_report


def test_console_formats():
    assert fmt_percent(-0.00568827) == "-0.57 %"
    assert fmt_percent(0.0191, 1, False) == "1.9 %"
    assert fmt_value(-1.11e-16, scale=3.0) == "0"
    assert fmt_value(5.168914321) == "5.16891"
    assert fmt_value(None) == fmt_value(float("nan")) == "n/a"


def _diagnosis(tmp_path):
    d = {"verdict": "missing_physics", "summary": ["The data show an unmodelled mass at floor 4."],
         "findings": [{"physics": "added_mass", "location": {"floor": 4},
                       "parameters": {"dm4": 1.2034}, "uncertainty": {"dm4": 0.0013},
                       "evidence": {"delta_bic": -1.06e6, "held_out_chi2": 0.9986},
                       "statement": "An added mass of 1.20 kg at floor 4."}],
         "alternatives": [], "absorbed": [{"physics": "added_mass", "location": {"floor": 1},
                                           "fraction_left": 0.012}],
         "fit": {"before": {"objective": 530569.0, "reduced_chi2": 975.3, "held_out_chi2": 4207.7},
                 "after": {"objective": 626.9, "reduced_chi2": 1.153, "held_out_chi2": 0.9986}},
         "suggested_measurements": ["a second shaker position"],
         "provenance": {"version": "9.9", "date_utc": "2026-01-01T00:00:00Z",
                        "files": {"case.yaml": {"sha256": "ab" * 32, "bytes": 10}}}}
    (tmp_path / "diagnosis.json").write_text(json.dumps(d))
    (tmp_path / "residual_map.png").write_bytes(b"")
    return d


def test_diagnosis_report_rebuilds_with_findings_and_provenance(tmp_path):
    _diagnosis(tmp_path)
    path = write_report(str(tmp_path))
    page = open(path).read()
    # 1.2034 kg with an error of 0.0013 kg: 0.108 % of it
    assert "missing physics" in page and "added mass dm = 1.2 kg (± 0.11 %)" in page
    assert "at floor 4" in page and 'src="residual_map.png"' in page
    # an absorbed entry the fitted parameters do not point at (no indicator) is not listed
    assert "fraction left" not in page and "absorbed" not in page.split("<h2>Fit")[0].lower()
    assert "9.9" in page and "sha256 abababababab" in page
    assert write_report(str(tmp_path)) == path and open(path).read() == page


BASE = {"physics": "base_flexibility", "location": {},
        "parameters": {"m_base": 2.5, "log10_kb": 5.941, "c_base": 3.0},
        "uncertainty": {"m_base": 0.05, "log10_kb": 0.029, "c_base": 0.6},
        "evidence": {"delta_bic": -420.0, "held_out_chi2": 1.1},
        "statement": "The data show a flexible base (log10_kb = 5.941 +- 0.029)."}


def _base_diagnosis(tmp_path):
    d = {"verdict": "missing_physics", "findings": [BASE], "alternatives": [],
         "summary": [BASE["statement"]],
         "absorbed": [{"physics": "added_mass", "location": {"floor": 3}, "fraction_left": 0.0,
                       "indicator": "m3 is +12.0 +- 3.0 % of nominal"}],
         "fitted_parameters": [{"parameter": "m3", "group": "mass", "nominal": 5.0,
                                "value": 5.6, "relative_change": 0.12,
                                "standard_error": 0.03, "prior_sigma": 0.05, "z_prior": 2.4}],
         "fit": {"before": {"objective": 900.0, "reduced_chi2": 9.0, "held_out_chi2": 12.0,
                            "reduced_chi2_sd": 0.2, "effective_points": 50},
                 "after": {"objective": 100.0, "reduced_chi2": 1.02, "held_out_chi2": 1.1}},
         "suggested_measurements": [], "remaining_mismatch": False,
         "provenance": {"version": "9.9", "date_utc": "2026-01-01T00:00:00Z"}}
    (tmp_path / "diagnosis.json").write_text(json.dumps(d))
    return d


def _k_b(text):
    """(value [N/m], relative error) of the base stiffness as written in text."""
    m = re.search(r"k_b = ([0-9.e+-]+) N/m \(± ([0-9.]+) %\)", text)
    assert m, text
    return float(m.group(1)), float(m.group(2)) / 100


def test_log10_parameter_in_physical_units_with_its_relative_error(tmp_path):
    """log10_kb = 5.941 +- 0.029 is k_b = 10^5.941 = 8.73e5 N/m with a relative error of
    ln(10) x 0.029 = 6.7 %: checked against the formula and against a central difference
    of 10^v, in the printed conclusion and in report.html."""
    v, se = 5.941, 0.029
    rel_fd = (10 ** (v + 1e-6) - 10 ** (v - 1e-6)) / 2e-6 * se / 10 ** v
    assert rel_fd == pytest.approx(math.log(10) * se, rel=1e-6)
    d = _base_diagnosis(tmp_path)
    lines = []
    log_conclusion(lines.append, d)
    printed = "\n".join(lines)
    page = open(write_report(str(tmp_path))).read()
    for text in (printed, page):
        k, rel = _k_b(text)
        assert k == pytest.approx(10 ** v, rel=5e-3)          # 3 significant figures
        assert rel == pytest.approx(rel_fd, abs=5e-4)         # 2 significant figures
        assert "log10_kb" not in text.split("Provenance")[0].replace(BASE["statement"], "")
    assert "base mass m_b = 2.5 kg (± 2 %)" in printed       # 0.05 / 2.5
    assert "base dashpot c_b = 3 N s/m (± 20 %)" in printed  # 0.6 / 3


def test_report_reads_verdict_findings_words_then_provenance(tmp_path):
    _base_diagnosis(tmp_path)
    page = open(write_report(str(tmp_path))).read()
    order = [page.index(s) for s in ("Verdict:", "<h2>Findings", "<h2>In plain words",
                                     "<h2>Fit before", "<h2>Provenance")]
    assert order == sorted(order)
    words = page[order[2]:order[3]]
    # what, where, how big, how much the fit improved
    assert "a flexible base in the whole structure" in words
    assert "from 9 to 1.02" in words and "from 12 to 1.1" in words
    # the absorbed mass is worded as a hypothesis, from the fitted mass and its error
    assert "mass of floor 3 rose 12 % (4 standard errors, 2.4 prior sigmas)" in words
    assert "hypothesis, not a finding" in words


def test_importing_the_package_leaves_the_matplotlib_backend_alone():
    code = ("import matplotlib; matplotlib.use('svg'); import nlp.output.plots, "
            "nlp.diagnosis.plots, nlp.workflow.verify, nlp.frf.freqsel, nlp.output.report; "
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "svg"


def test_the_joints_section_says_what_was_divided_out_and_whether_it_held():
    from nlp.output.report import _sweep_section
    sw = {"stories": [1, 2], "change": [-0.0081, 0.0074], "k3": [-6.0e4, 1.4e5],
          "k3_se": [3.0e3, 9.0e3], "largest_ln_change": 0.07, "reduced_chi2": [8.94, 0.9]}
    html_ = "".join(_sweep_section(sw))
    assert "-0.81 %" in html_ and "+0.74 %" in html_ and "-6e+04 +- 3e+03" in html_
    assert "from 8.94 to 0.9" in html_ and "before the diagnosis" in html_
    assert "no longer proven" not in html_
    late = "".join(_sweep_section(dict(sw, after_findings=True, confirmed=False)))
    assert "after the findings" in late and "no longer proven" in late
    assert _sweep_section(None) == []
