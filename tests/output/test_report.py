"""report.html of a run and of a diagnosis, from hand-written result files: numbers shown as
the console shows them, the physical C, units in words, provenance; no backend switch."""

import json
import subprocess
import sys


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
    assert "missing physics" in page and "dm4 = 1.203 ± 0.0013" in page
    assert "floor 4" in page and "1.2 %" in page and 'src="residual_map.png"' in page
    assert "9.9" in page and "sha256 abababababab" in page
    assert write_report(str(tmp_path)) == path and open(path).read() == page


def test_importing_the_package_leaves_the_matplotlib_backend_alone():
    code = ("import matplotlib; matplotlib.use('svg'); import nlp.output.plots, "
            "nlp.diagnosis.plots, nlp.workflow.verify, nlp.frf.freqsel, nlp.output.report; "
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "svg"
