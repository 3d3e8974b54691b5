"""scripts/score_lab.py's figures: in-catalogue detection split by what the records determine."""

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
from score_lab import summary  # noqa: E402


def _row(ok, detectable=None, fam="added_mass"):
    r = {"case": "c", "category": "in_catalogue", "exit": 0, "ok": ok, "extra": [],
         "set_up": [], "found": [], "families": [fam], "n_found": 1}
    if detectable is not None:
        r["detectable"] = detectable
    return r


def test_undetectable_effects_are_counted_apart(capsys):
    summary([_row(True, True), _row(False, True), _row(False, False), _row(True, False)])
    out = capsys.readouterr().out
    assert "in_catalogue      right 2/4" in out
    assert "detectable by the records: right 1/2 (50 %" in out
    assert "not detectable: 2 (named anyway: 1)" in out


def test_rows_scored_before_the_rule_count_as_detectable(capsys):
    summary([_row(True), _row(False)])
    assert "detectable by the records" not in capsys.readouterr().out
