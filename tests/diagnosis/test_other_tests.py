"""Another test of the structure whose data allow no fit is left out with its reason, not a
stop of the whole diagnosis; an error in the case file itself still stops it."""

import numpy as np
import pytest

from nlp.case.load import load_case
from nlp.diagnosis.others import assemble_other
from nlp.diagnosis.driver import diagnose
from nlp.errors import InputError
from nlp.testing.benchmark import make_case


def _two_level_null(folder, seed=12):
    make_case(folder, {"storeys": 3, "seconds": 600.0, "excitation": "force", "family": None,
                       "ordinary": False, "levels": 2}, seed)
    return folder + "/case.yaml", folder + "/records_level2.csv"


def _replace_responses(path, rows):
    """The level file's responses replaced by rows(t, input) -> (a1, a2, a3); time and
    input kept as written (their text, so the sampling stays exact)."""
    lines = open(path).read().splitlines()
    out = [lines[0]]
    for ln in lines[1:]:
        c = ln.split(",")
        out.append(",".join(c[:2] + [f"{v:.6e}" for v in rows(float(c[0]), float(c[1]))]))
    with open(path, "w") as fh:
        fh.write("\n".join(out) + "\n")


def test_a_level_file_of_dead_channels_is_left_out_with_its_reason(tmp_path):
    case_file, level = _two_level_null(str(tmp_path / "case"))
    rng = np.random.default_rng(0)
    _replace_responses(level, lambda t, u: rng.standard_normal(3))   # no coherence with u
    said = []
    c, why = assemble_other(load_case(case_file), level, said.append)
    assert c is None and "coherent with the input" in why and "largest coherence" in why
    assert said and "records_level2.csv not used" in said[0]
    # the main file is untouched: it still assembles
    c, why = assemble_other(load_case(case_file), str(tmp_path / "case" / "records.csv"))
    assert why is None and c.selected.size > 0


def test_an_error_of_the_case_file_still_stops(tmp_path):
    case_file, level = _two_level_null(str(tmp_path / "case"))
    cfg = load_case(case_file)
    lines = open(level).read().splitlines()   # a column the case file names is missing
    with open(level, "w") as fh:
        fh.write("\n".join(",".join(ln.split(",")[:4]) for ln in lines) + "\n")
    with pytest.raises(InputError):
        assemble_other(cfg, level, lambda *_: None)


@pytest.mark.slow  # one diagnosis of a small two-level case (~30 s)
def test_diagnosis_goes_on_without_a_level_whose_data_allow_no_fit(tmp_path):
    case_file, level = _two_level_null(str(tmp_path / "case"))
    rng = np.random.default_rng(1)
    _replace_responses(level, lambda t, u: rng.standard_normal(3))
    res = diagnose(load_case(case_file), str(tmp_path / "out"), log=lambda *_: None)
    assert res["verdict"] == "adequate", res["findings"]
    lc = res["level_comparison"]
    assert lc["found"] is False and lc["max_z"] is None
    assert [x["file"] for x in lc["not_compared"]] == ["records_level2.csv"]
