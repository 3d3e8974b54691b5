"""Score `frf-nlp diagnose` on the lab benchmark (scripts/make_lab_benchmark.py).

    python scripts/score_lab.py --bench lab [--only 00,32] [--timeout 1800] [--summary-only] [--exam]

Each case runs as `python -m nlp diagnose CASE/case.yaml --out CASE/diagnosis`, one at a
time; truth.json is read afterwards. One JSON line per case goes to BENCH/scores.jsonl as
soon as it finishes (an interrupted scoring resumes). Without --exam only development
seeds (0-99) are scored: an exam seed is scored once, by the protocol of issue 48.

Per category (docs/benchmarks/lab_generator.md):
* null_lab: right when the verdict is `adequate` or `setup_error`, or every finding is a
  calibration or timing one (sensor_gain, sensor_delay); otherwise a false alarm;
* in_catalogue: the effect found with its family and location; other findings are wrong
  extra findings;
* out_of_catalogue: `partly_explained` (a finding with a remaining mismatch) or
  `ambiguous`, and some finding, tie or unconfirmed candidate names the location;
  `missing_physics` with nothing remaining is a confident wrong answer;
* non_shear: a verdict in the truth's list, no finding outside the truth's acceptable families
  (frame_action, nonadjacent_coupling, and the set-up ones), and, where the truth says so
  (must_name_one_of), non-shear behaviour named by frame_action or a non-adjacent coupling;
* torsion: `partly_explained` or `ambiguous`.
Rates carry Wilson 95 % intervals.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from nlp.solve.executors.threads import limit_blas_threads

SETUP = ("sensor_gain", "sensor_delay")


def wilson(k, n, z=1.96):
    """Wilson score interval of k successes in n."""
    if n == 0:
        return (float("nan"), float("nan"))
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(c - h, 0.0), min(c + h, 1.0))


def label(res):
    """The verdict, with `missing_physics` plus a remaining mismatch read as partly_explained."""
    if res is None:
        return None
    v = res["verdict"]
    return "partly_explained" if v == "missing_physics" and res.get("remaining_mismatch") else v


def same_location(a, b):
    if "between" in a and "between" in b:
        return sorted(a["between"]) == sorted(b["between"])
    return a == b


def named(res, where):
    """Does any finding, tie, unconfirmed candidate or alternative name the location?"""
    keys = ("findings", "indistinguishable", "unconfirmed", "alternatives")
    return any(same_location(r.get("location", {}), where) for k in keys for r in (res or {}).get(k, []))


def judge(truth, res):
    """One case's verdict label, whether it is right, and its wrong extra findings."""
    cat, lab = truth["category"], label(res)
    fams = [f["physics"] for f in (res or {}).get("findings", [])]
    extra = []
    if cat == "null_lab":
        ok = lab in truth["acceptable_verdicts"] or (fams and all(f in SETUP for f in fams))
    elif cat == "in_catalogue":
        found = res.get("findings", []) if res else []
        ok = all(any(f["physics"] == e["family"] and same_location(f["location"], e["location"])
                     for f in found) for e in truth["effects"])
        extra = [f["physics"] for f in found
                 if not any(f["physics"] == e["family"] for e in truth["effects"])]
    elif cat == "out_of_catalogue":
        ok = lab in truth["acceptable_verdicts"] and named(res, truth["location"])
    elif cat == "non_shear":
        extra = [f for f in fams if f not in truth.get("acceptable_families", [])]
        must = truth.get("must_name_one_of")
        ok = lab in truth["acceptable_verdicts"] and not extra and (
            not must or any(f in must for f in fams))
    else:
        ok = lab in truth["acceptable_verdicts"]
    return lab, bool(ok), extra


def run(folder, timeout):
    out = os.path.join(folder, "diagnosis")
    cmd = [sys.executable, "-m", "nlp", "diagnose", os.path.join(folder, "case.yaml"), "--out", out]
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        code = p.returncode
        err = p.stderr.strip().splitlines()[-1:] if code else []
    except subprocess.TimeoutExpired:
        code, err = "timeout", [f"no result within {timeout} s"]
    res = None
    path = os.path.join(out, "diagnosis.json")
    if code == 0 and os.path.isfile(path):
        with open(path) as fh:
            res = json.load(fh)
    return code, err, time.perf_counter() - t0, res


def line(r):
    return (f"{r['case']:42s} {r['category']:17s} verdict {str(r['label']):17s} "
            f"{'ok' if r['ok'] else 'WRONG':5s} {r['seconds']:.0f} s"
            + (f"  exit {r['exit']}: {' '.join(r['error'])}" if r["exit"] != 0 else "")
            + ("  found: " + "; ".join(r["found"]) if r["found"] else ""))


def summary(rows):
    print()
    for cat in ("null_lab", "in_catalogue", "out_of_catalogue", "non_shear", "torsion"):
        rs = [r for r in rows if r["category"] == cat]
        if rs:
            k = sum(r["ok"] for r in rs)
            lo, hi = wilson(k, len(rs))
            print(f"{cat:17s} right {k}/{len(rs)} ({100 * k / len(rs):.0f} %, Wilson 95 % "
                  f"{100 * lo:.0f}-{100 * hi:.0f} %)")
    eff = [r for r in rows if r["category"] == "in_catalogue"]
    wrong = sum(bool(r["extra"]) for r in eff)
    if eff:
        print(f"in_catalogue cases with a wrong extra finding: {wrong}/{len(eff)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="lab")
    ap.add_argument("--timeout", type=float, default=1800.0)
    ap.add_argument("--only", help="comma-separated case-name prefixes, run in this order")
    ap.add_argument("--summary-only", action="store_true")
    ap.add_argument("--exam", action="store_true", help="allow seeds >= 100 (an exam, scored once)")
    a = ap.parse_args()
    log = os.path.join(a.bench, "scores.jsonl")
    rows = {}
    if os.path.isfile(log):
        with open(log) as fh:
            rows = {r["case"]: r for r in map(json.loads, filter(str.strip, fh))}
    names = sorted(d for d in os.listdir(a.bench) if os.path.isfile(os.path.join(a.bench, d, "truth.json")))
    if a.only:
        names = list(dict.fromkeys(d for p in a.only.split(",") for d in names if d.startswith(p)))
    for name in names:
        if name in rows:
            print(line(rows[name]), flush=True)
            continue
        if a.summary_only:
            continue
        folder = os.path.join(a.bench, name)
        with open(os.path.join(folder, "truth.json")) as fh:
            truth = json.load(fh)
        if truth["seed"] // 1000 >= 100 and not a.exam:
            print(f"{name}: seed {truth['seed'] // 1000} is not a development seed (0-99); "
                  "pass --exam to score an exam once", file=sys.stderr)
            return 2
        code, err, seconds, res = run(folder, a.timeout)
        lab, ok, extra = judge(truth, res)
        r = {"case": name, "category": truth["category"], "exit": code, "error": err,
             "seconds": seconds, "verdict": res["verdict"] if res else None, "label": lab, "ok": ok,
             "extra": extra, "development": truth["seed"] // 1000 < 100,
             "found": [f"{f['physics']} {f['location']}" for f in (res or {}).get("findings", [])]}
        with open(log, "a") as fh:
            fh.write(json.dumps(r) + "\n")
        rows[name] = r
        print(line(r), flush=True)
    summary([rows[n] for n in names if n in rows])
    return 0


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    sys.exit(main())
