"""Would the correlated-residual evidence refuse the wrong findings and keep the right ones?

Reads scored benchmarks (scores.jsonl of score_lab.py, score_blind.py or
score_planted_real.py, with each case's diagnosis.json; on a planted set a finding is right
when it is the planted effect, wrong when it is neither planted nor in the control) made by a version that records
`correlation_factor` and `delta_bic_correlated` in each finding's evidence (docs/method/
diagnosis.md, section 4), labels each accepted catalogue finding right or wrong from the
score line, and counts how many of each would still pass BIC_ACCEPT with the drop divided by
the factor. Development seeds only: a rule chosen on these counts must be scored afresh.

    python research/correlated_evidence.py BENCH [BENCH ...]
"""

import argparse
import importlib.util
import json
import os

from nlp.diagnosis.evidence import BIC_ACCEPT

_spec = importlib.util.spec_from_file_location(
    "score_planted_real", os.path.join(os.path.dirname(__file__), "..", "scripts",
                                       "score_planted_real.py"))
planted = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(planted)


def _diagnosis(bench, case):
    for sub in ("diagnosis/diagnosis.json", "diagnosis.json"):
        p = os.path.join(bench, case, sub)
        if os.path.exists(p):
            with open(p) as fh:
                return json.load(fh)
    return None


def _wrong(row, key, f=None, control=None):
    """Whether the finding "family location" is wrong by the score line's own labels (None:
    not labelled, as a planted case's finding its control shares)."""
    if "truth" in row and "findings" in row:                # score_planted_real.py
        if control is not None and planted.key(f) in {planted.key(c) for c in control["findings"]}:
            return None
        return row["truth"]["family"] is None or planted.key(f) != planted.key(row["truth"])
    if "extra" in row:                                      # score_lab.py
        return key in row["extra"]
    if row.get("kind") == "null":                           # score_blind.py
        return True
    if "effects" in row:
        return not any(key.startswith(e["family"]) and e.get("location_ok") for e in row["effects"])
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("benches", nargs="+")
    a = ap.parse_args()
    tally = {True: [0, 0], False: [0, 0]}          # wrong? -> [findings, still passing]
    for bench in a.benches:
        with open(os.path.join(bench, "scores.jsonl")) as fh:
            rows = [json.loads(line) for line in fh if line.strip()]
        controls = [r for r in rows if r["case"].endswith("_control")]
        for row in rows:
            if row["case"].endswith("_control"):
                continue
            d = _diagnosis(bench, row["case"])
            for f in (d or {}).get("findings", []):
                e = f.get("evidence") or {}
                if e.get("correlation_factor") is None:
                    continue
                key = f"{f['physics']} {f.get('location')}"
                wrong = _wrong(row, key, f, controls[0] if controls else None)
                passes = e["delta_bic_correlated"] <= -BIC_ACCEPT
                print(f"{row['case']:40s} {key:45s} dBIC {e['delta_bic']:10.1f} factor "
                      f"{e['correlation_factor']:6.2f} corrected {e['delta_bic_correlated']:10.1f} "
                      f"{'wrong' if wrong else 'right' if wrong is False else '?'}"
                      f"{'' if passes else '  (refused)'}")
                if wrong is not None:
                    tally[wrong][0] += 1
                    tally[wrong][1] += passes
    for wrong, (n, kept) in tally.items():
        print(f"{'wrong' if wrong else 'right'} findings: {n}, still accepted with the factor: {kept}")


if __name__ == "__main__":
    main()
