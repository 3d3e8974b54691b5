"""The lab scorer's figures (scripts/score_lab.py's summary, printed by scripts/exam_progress.py):
in-catalogue detection split by what the records determine."""

import json
import os
import subprocess
import sys

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "exam_progress.py")


def _row(k, ok, detectable=None):
    r = {"seed": 500, "case": f"{k:02d}_in_catalogue_added_mass", "category": "in_catalogue",
         "exit": 0, "seconds": 1.0, "label": "missing_physics", "ok": ok, "extra": [],
         "set_up": [], "found": [], "families": ["added_mass"], "n_found": 1}
    if detectable is not None:
        r["detectable"] = detectable
    return r


def _progress(tmp_path, rows):
    order = tmp_path / "order.txt"
    order.write_text("".join(f"500 {k:02d}\n" for k in range(len(rows))))
    scores = tmp_path / "scores.jsonl"
    scores.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return subprocess.run([sys.executable, SCRIPT, "--order", str(order), "--scores", str(scores)],
                          capture_output=True, text=True, check=True).stdout


def test_undetectable_effects_are_counted_apart(tmp_path):
    out = _progress(tmp_path, [_row(0, True, True), _row(1, False, True), _row(2, False, False),
                               _row(3, True, False)])
    assert "in_catalogue      right 2/4" in out
    assert "detectable by the records: right 1/2 (50 %" in out
    assert "not detectable: 2 (named anyway: 1)" in out


def test_rows_scored_before_the_rule_count_as_detectable(tmp_path):
    out = _progress(tmp_path, [_row(0, True), _row(1, False)])
    assert "in_catalogue      right 1/2" in out and "detectable by the records" not in out
