"""Run `diagnose` blind on every benchmark case and score it against truth.json.

    python scripts/score_benchmark.py [--bench benchmark] [--out DIR]

Prints a table: family x verdict, location accuracy, false alarms on null and
ordinary-change cases, median held-out error reduction. The diagnosis reads
only case.yaml and the records; truth.json is read here, after it has run.
"""

import argparse
import json
import os
import sys
import time
from collections import Counter, defaultdict

import numpy as np

from nlp.case.load import load_case
from nlp.diagnosis.driver import diagnose
from nlp.solve.executors.threads import limit_blas_threads


def _same_location(a, b):
    if "between" in a and "between" in b:
        return sorted(a["between"]) == sorted(b["between"])
    return a == b


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="benchmark")
    ap.add_argument("--out", default=None, help="diagnosis folders (default: <case>/diagnosis)")
    a = ap.parse_args()
    rows = []
    for name in sorted(os.listdir(a.bench)):
        folder = os.path.join(a.bench, name)
        if not os.path.isfile(os.path.join(folder, "case.yaml")):
            continue
        t0 = time.perf_counter()
        out = os.path.join(a.out or folder, "diagnosis" if a.out is None else name)
        res = diagnose(load_case(os.path.join(folder, "case.yaml")), out, log=lambda *_: None)
        with open(os.path.join(folder, "truth.json")) as fh:
            truth = json.load(fh)
        fam = truth["family"]
        found = res["findings"][0] if res["findings"] else None
        fam_ok = found is not None and found["physics"] == fam
        loc_ok = fam_ok and _same_location(found["location"], truth["location"])
        fb, fa = res["fit"]["before"], res["fit"]["after"]
        key = "other_level_held_out_chi2" if "other_level_held_out_chi2" in fa else "held_out_chi2"
        before, after = fb[key], fa[key]
        rows.append({"case": name, "family": fam or "none", "verdict": res["verdict"],
                     "found": found["physics"] if found else "-", "family_ok": fam_ok,
                     "location_ok": loc_ok, "held_out_ratio": after / before,
                     "seconds": time.perf_counter() - t0})
        r = rows[-1]
        print(f"{name:28s} truth {r['family']:22s} verdict {r['verdict']:16s} found "
              f"{r['found']:22s} loc {'ok' if loc_ok else '--'}  held-out x{r['held_out_ratio']:.3f}"
              f"  {r['seconds']:.0f} s", flush=True)
    _table(rows)


def _table(rows):
    print("\nfamily                 cases  adequate  missing  ambiguous  family ok  location ok")
    by = defaultdict(list)
    for r in rows:
        by[r["family"]].append(r)
    for fam, rs in sorted(by.items()):
        v = Counter(r["verdict"] for r in rs)
        print(f"{fam:22s} {len(rs):5d} {v['adequate']:9d} {v['missing_physics']:8d} "
              f"{v['ambiguous']:10d} {sum(r['family_ok'] for r in rs):10d} "
              f"{sum(r['location_ok'] for r in rs):12d}")
    eff = [r for r in rows if r["family"] != "none"]
    null = [r for r in rows if r["family"] == "none"]
    # a planted gain or delay alone is a set-up error (nlp.diagnosis.verdict.classify)
    acc = [r for r in eff if r["verdict"] in ("missing_physics", "setup_error") and r["family_ok"]]
    print(f"\ncorrect family and location: {sum(r['location_ok'] for r in eff)}/{len(eff)} effect cases"
          f" ({100 * np.mean([r['location_ok'] for r in eff]):.0f} %)" if eff else "")
    print(f"false alarms (null and ordinary-change cases not 'adequate'): "
          f"{sum(r['verdict'] != 'adequate' for r in null)}/{len(null)}")
    if acc:
        ratio = np.median([r["held_out_ratio"] for r in acc])
        print(f"median held-out chi-square ratio (after/before) when the right physics is accepted: "
              f"{ratio:.3f} (RMS error ratio {np.sqrt(ratio):.3f})")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    sys.exit(main())
