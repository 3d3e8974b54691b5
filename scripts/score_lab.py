"""Score `frf-nlp diagnose` on the lab benchmark (scripts/make_lab_benchmark.py).

    python scripts/score_lab.py --bench lab [--only 00,32] [--timeout 1800] [--budget 25]
                                [--summary-only] [--exam]

Each case runs as `python -m nlp diagnose CASE/case.yaml --out CASE/diagnosis`, one at a
time; truth.json is read afterwards. One JSON line per case goes to BENCH/scores.jsonl as
soon as it finishes (an interrupted scoring resumes). Without --exam only development
seeds (0-99) are scored: an exam seed is scored once, by the protocol of issue 48.

Per category (docs/benchmarks/lab_generator.md):
* null_lab: right when the verdict is `adequate` or `setup_error`, or every finding is a
  calibration or timing one (sensor_gain, sensor_delay); otherwise a false alarm;
* in_catalogue: the effect found with its family and location; other structural findings are
  wrong extra findings (calibration and timing findings are counted apart: the lab has them);
* out_of_catalogue: `partly_explained` (a finding with a remaining mismatch) or
  `ambiguous`, and some finding, tie or unconfirmed candidate names the location;
  `missing_physics` with nothing remaining is a confident wrong answer;
* non_shear: a verdict in the truth's list, no finding outside the truth's acceptable families
  (frame_action, nonadjacent_coupling, and the set-up ones), and, where the truth says so
  (must_name_one_of), non-shear behaviour named by frame_action or a non-adjacent coupling;
* torsion: `partly_explained` or `ambiguous`; a structural finding there is a wrong extra one.
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
    """One case's verdict label, whether it is right, and its wrong extra findings
    ("family location"). On an effect case a wrong extra finding is a structural finding that
    matches no planted effect in family and location; calibration and timing findings
    (SETUP) that match none are the lab's own imperfections, counted apart (set_up)."""
    cat, lab = truth["category"], label(res)
    found = (res or {}).get("findings", [])
    fams = [f["physics"] for f in found]
    extra, set_up = [], []
    if cat == "null_lab":
        ok = lab in truth["acceptable_verdicts"] or (fams and all(f in SETUP for f in fams))
    elif cat == "in_catalogue":
        def planted(f):
            return any(f["physics"] == e["family"] and same_location(f.get("location", {}), e["location"])
                       for e in truth["effects"])
        ok = all(any(f["physics"] == e["family"] and same_location(f.get("location", {}), e["location"])
                     for f in found) for e in truth["effects"])
        for f in found:
            if not planted(f):
                (set_up if f["physics"] in SETUP else extra).append(f"{f['physics']} {f.get('location')}")
    elif cat == "out_of_catalogue":
        ok = lab in truth["acceptable_verdicts"] and named(res, truth["location"])
    elif cat == "non_shear":
        extra = [f for f in fams if f not in truth.get("acceptable_families", [])]
        must = truth.get("must_name_one_of")
        ok = lab in truth["acceptable_verdicts"] and not extra and (
            not must or any(f in must for f in fams))
    else:   # torsion: no catalogue family describes it, so a structural finding is wrong
        ok = lab in truth["acceptable_verdicts"]
        extra = [f for f in fams if f not in SETUP]
    return lab, bool(ok), extra, set_up


def run(folder, timeout, budget=None):
    """Diagnose one case (budget [min]: diagnose --budget, None for none)."""
    out = os.path.join(folder, "diagnosis")
    cmd = [sys.executable, "-m", "nlp", "diagnose", os.path.join(folder, "case.yaml"), "--out", out]
    cmd += ["--budget", str(budget)] if budget else []
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        code = p.returncode
        err = p.stderr.strip().splitlines()[-1:] if code else []
        text = p.stdout + p.stderr
    except subprocess.TimeoutExpired as e:
        code, err = "timeout", [f"no result within {timeout} s"]
        text = e.stdout.decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
    # the diagnosis's own log, beside its result, for reading a development case afterwards
    with open(os.path.join(folder, "diagnosis.log"), "w") as fh:
        fh.write(text)
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


def _rate(k, n):
    lo, hi = wilson(k, n)
    return f"{k}/{n} ({100 * k / n:.0f} %, Wilson 95 % {100 * lo:.0f}-{100 * hi:.0f} %)" if n else "0/0"


def summary(rows):
    """The figures issue 48 asks for, each with its Wilson 95 % interval."""
    print()
    for cat in ("null_lab", "in_catalogue", "out_of_catalogue", "non_shear", "torsion"):
        rs = [r for r in rows if r["category"] == cat]
        if rs:
            print(f"{cat:17s} right {_rate(sum(r['ok'] for r in rs), len(rs))}")
    nulls = [r for r in rows if r["category"] == "null_lab"]
    if nulls:
        print(f"false alarms on nulls: {_rate(sum(not r['ok'] for r in nulls), len(nulls))}")
    eff = [r for r in rows if r["category"] == "in_catalogue"]
    det = [r for r in eff if r.get("detectable", True)]
    if len(det) < len(eff):   # truth.json's detectability (nlp/testing/lab/detectable.py)
        right = sum(r["ok"] for r in det)
        print(f"in_catalogue, detectable by the records: right {_rate(right, len(det))}; "
              f"not detectable: {len(eff) - len(det)} (named anyway: "
              f"{sum(r['ok'] for r in eff) - right})")
    for fam in sorted({f for r in eff for f in r.get("families", [])}):
        rs = [r for r in eff if fam in r.get("families", [])]
        print(f"  detection, {fam:22s} {_rate(sum(r['ok'] for r in rs), len(rs))}")
    effect = [r for r in rows if r["category"] in ("in_catalogue", "non_shear", "torsion")]
    n_found = sum(r.get("n_found", len(r["found"])) for r in effect)
    n_extra = sum(len(r["extra"]) for r in effect)
    if effect:
        print(f"wrong extra findings on effect cases (in_catalogue, non_shear, torsion): "
              f"{_rate(n_extra, n_found)} of accepted findings; cases with one: "
              f"{sum(bool(r['extra']) for r in effect)}/{len(effect)}")
        print(f"set-up findings (calibration, timing) beside a planted effect: "
              f"{sum(len(r.get('set_up', [])) for r in eff)} in {len(eff)} in-catalogue cases")
    ooc = [r for r in rows if r["category"] == "out_of_catalogue"]
    if ooc:
        print(f"out-of-catalogue effects reported partly_explained or ambiguous at the right "
              f"location: {_rate(sum(r['ok'] for r in ooc), len(ooc))}")
    slow = [r for r in rows if r["exit"] != 0]
    if slow:
        print(f"no result (timeout or error, counted wrong): {len(slow)}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="lab")
    ap.add_argument("--timeout", type=float, default=1800.0)
    ap.add_argument("--budget", type=float, help="diagnose --budget MINUTES: no stage starts "
                    "after it, so the case ends with a verdict before --timeout")
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
        code, err, seconds, res = run(folder, a.timeout, a.budget)
        lab, ok, extra, set_up = judge(truth, res)
        r = {"case": name, "category": truth["category"], "exit": code, "error": err,
             "seconds": seconds, "verdict": res["verdict"] if res else None, "label": lab, "ok": ok,
             "extra": extra, "set_up": set_up, "n_found": len((res or {}).get("findings", [])),
             "families": [e["family"] for e in truth.get("effects", [])],
             "detectable": (truth.get("detectability") or {}).get("detectable", True),
             "development": truth["seed"] // 1000 < 100,
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
