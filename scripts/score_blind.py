"""Score `frf-nlp diagnose` on the blind benchmark (scripts/make_blind_benchmark.py).

    python scripts/score_blind.py --bench blind [--timeout 900] [--only 00,13] [--jobs 2] [--summary-only]

Each case runs as its own `python -m nlp diagnose CASE.yaml --out CASE/diagnosis`
subprocess with a time limit; the diagnosis reads only case.yaml and the data.
--jobs N runs N cases at once (each case file asks for one worker).
truth.json is read here, afterwards. One JSON line per case is appended to
BENCH/scores.jsonl as soon as the case finishes, so an interrupted scoring resumes
where it stopped (cases already in the file are not run again; delete the file
to start over).

Printed: one line per case, then
* correct family and location (each concealed effect counts; an effect is found
  when a finding, or the nonlinearity finding, names its family and location),
  over all effects and over the detectable ones (size rank >= 2 of the five
  sizes of its family, fixed before any scoring);
* false alarms: null and ordinary-change cases whose verdict is not `adequate`;
* wrong extra findings: accepted findings on effect cases beyond the effects found
  with the right family and location;
  set-up errors claimed on any case (the benchmark has none);
* the median held-out chi-square ratio (after / before) when the right physics
  is accepted;
* the baseline reduced chi-square of null and ordinary cases per FRF route
  (one-segment transient, Welch, FRF file);
* the detection-limit table: per family, detection rate at each effect size.
"""

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from collections import defaultdict

import numpy as np

from nlp.testing.blind.structures import SIZE_DETECTABLE, SIZES
from nlp.solve.executors.threads import limit_blas_threads


def _same_location(a, b):
    if "between" in a and "between" in b:
        return sorted(a["between"]) == sorted(b["between"])
    return a == b


def _run(folder, timeout):
    out = os.path.join(folder, "diagnosis")
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "nlp", "diagnose", os.path.join(folder, "case.yaml"), "--out", out]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        code, err = p.returncode, p.stderr.strip().splitlines()[-1:] if p.returncode else []
    except subprocess.TimeoutExpired:
        code, err = "timeout", [f"no result within {timeout} s"]
    seconds = time.perf_counter() - t0
    res = None
    path = os.path.join(out, "diagnosis.json")
    if code == 0 and os.path.isfile(path):
        with open(path) as fh:
            res = json.load(fh)
    return code, err, seconds, res


def score_case(name, truth, code, err, seconds, res, sizes):
    """One row: the truth, what diagnose said, and whether each effect was found."""
    found = (res or {}).get("findings", [])
    effects = []
    for e in truth["effects"]:
        hit = [f for f in found if f["physics"] == e["family"]]
        ok_loc = any(_same_location(f["location"], e["location"]) for f in hit)
        rank = sizes[e["family"]].index(e["size"]) if e["size"] in sizes[e["family"]] else 3
        effects.append({"family": e["family"], "size": e["size"], "rank": rank,
                        "family_ok": bool(hit), "location_ok": ok_loc})
    fit = (res or {}).get("fit", {})
    before, after = fit.get("before", {}), fit.get("after", {})
    key = "other_level_held_out_chi2" if "other_level_held_out_chi2" in after else "held_out_chi2"
    ratio = (after[key] / before[key]) if before.get(key) and key in after else None
    return {"case": name, "exit": code, "error": err, "seconds": seconds,
            "verdict": res["verdict"] if res else None, "route": truth["route"],
            "kind": "effect" if truth["effects"] else ("ordinary" if truth["ordinary"] else "null"),
            "effects": effects, "found": [f"{f['physics']} {f['location']}" for f in found],
            "baseline_reduced_chi2": before.get("reduced_chi2"), "held_out_ratio": ratio,
            # a right noise model's spread on the case's own points (nlp/diagnosis/spread.py)
            "baseline_chi2_sd": before.get("reduced_chi2_sd"),
            # degrees of freedom of the baseline fit: objective = chi-square / 2
            "baseline_dof": (2 * before["objective"] / before["reduced_chi2"]
                             if before.get("reduced_chi2") and before.get("objective") else None)}


def _line(r):
    truth = " + ".join(f"{e['family']}[{e['rank']}]" for e in r["effects"]) or r["kind"]
    ok = " ".join("ok" if e["location_ok"] else ("fam" if e["family_ok"] else "--")
                  for e in r["effects"]) or ("ok" if r["verdict"] == "adequate" else "ALARM")
    chi = r["baseline_reduced_chi2"]
    ho = r["held_out_ratio"]
    return (f"{r['case']:44s} {r['route']:11s} truth {truth:44s} verdict {str(r['verdict']):15s} "
            f"{ok:6s} chi2 {chi if chi is None else f'{chi:.2f}'!s:6s} held-out "
            f"x{ho if ho is None else f'{ho:.3f}'!s:6s} {r['seconds']:.0f} s"
            + (f"  exit {r['exit']}: {' '.join(r['error'])}" if r["exit"] != 0 else "")
            + ("  found: " + "; ".join(r["found"]) if r["found"] else ""))


def summary(rows, sizes):
    eff = [e for r in rows for e in r["effects"]]
    det = [e for e in eff if e["rank"] >= SIZE_DETECTABLE]
    quiet = [r for r in rows if r["kind"] != "effect"]
    pct = (lambda a, b: f"{100 * a / b:.0f} %" if b else "-")
    n_ok = sum(e["location_ok"] for e in eff)
    d_ok = sum(e["location_ok"] for e in det)
    print(f"\ncases scored: {len(rows)} ({sum(r['exit'] != 0 for r in rows)} without a result: "
          "input error, crash or timeout)")
    print(f"correct family and location, detectable effects (size rank >= {SIZE_DETECTABLE}): "
          f"{d_ok}/{len(det)} ({pct(d_ok, len(det))})")
    print(f"correct family and location, all effects: {n_ok}/{len(eff)} ({pct(n_ok, len(eff))})")
    fa = sum(r["verdict"] != "adequate" for r in quiet)
    print(f"false alarms (null and ordinary-change cases not 'adequate'): {fa}/{len(quiet)} "
          f"({pct(fa, len(quiet))})")
    # a finding on an effect case that names no concealed effect's family and location is an
    # error too: every accepted finding beyond the effects it found right
    n_found = sum(len(r["found"]) for r in rows if r["kind"] == "effect")
    n_extra = sum(max(len(r["found"]) - sum(e["location_ok"] for e in r["effects"]), 0)
                  for r in rows if r["kind"] == "effect")
    print(f"wrong extra findings on effect cases: {n_extra}/{n_found} accepted findings "
          f"({pct(n_extra, n_found)})")
    print(f"set-up errors claimed (the benchmark has none): "
          f"{sum(r['verdict'] == 'setup_error' for r in rows)}/{len(rows)}")
    ratios = [r["held_out_ratio"] for r in rows if r["kind"] == "effect" and r["held_out_ratio"]
              and any(e["location_ok"] for e in r["effects"])]
    if ratios:
        print(f"median held-out chi-square ratio (after/before) when the right physics is accepted: "
              f"{np.median(ratios):.3f} over {len(ratios)} cases")
    print("\nbaseline reduced chi-square, null and ordinary-change cases, per FRF route:")
    by = defaultdict(list)
    for r in quiet:
        if r["baseline_reduced_chi2"] is not None:
            by[r["route"]].append(r["baseline_reduced_chi2"])
    pooled = defaultdict(lambda: [0.0, 0.0])
    for r in quiet:
        if r["baseline_reduced_chi2"] is not None and r.get("baseline_dof"):
            pooled[r["route"]][0] += r["baseline_reduced_chi2"] * r["baseline_dof"]
            pooled[r["route"]][1] += r["baseline_dof"]
    for route in ("one_segment", "welch", "frf_file"):
        v = by.get(route, [])
        chi, dof = pooled.get(route, (0.0, 0.0))
        # pooled: the route's chi-square over its degrees of freedom, all its cases together
        print(f"  {route:12s} n={len(v):2d}  " + (f"median {np.median(v):.2f}  range {min(v):.2f}-"
                                                 f"{max(v):.2f}" if v else "-")
              + (f"  pooled {chi / dof:.2f} over {dof:.0f} degrees of freedom" if dof else ""))
        sds = [(r["baseline_reduced_chi2"], r["baseline_chi2_sd"]) for r in quiet
               if r["route"] == route and r.get("baseline_chi2_sd")
               and r["baseline_reduced_chi2"] is not None]
        if sds:
            # not the criterion (0.8-1.3): how many a right noise model explains
            print(f"  {'':12s} within 2 sampling SDs of 1 (the case's own spread): "
                  f"{sum(abs(c - 1) <= 2 * sd for c, sd in sds)}/{len(sds)}; SDs "
                  f"{min(sd for _, sd in sds):.2f}-{max(sd for _, sd in sds):.2f}")
    print("\ndetection limits: effects found with the right family and location, per size "
          "(size: the family's dimensionless measure; see SIZES in nlp/testing/blind/structures.py)")
    table = defaultdict(lambda: defaultdict(list))
    for e in eff:
        table[e["family"]][e["rank"]].append(e["location_ok"])
    print(f"{'family':22s} " + " ".join(f"{'size ' + str(k):>12s}" for k in range(5)))
    for fam in sizes:
        cells = []
        for k in range(5):
            v = table[fam].get(k, [])
            cells.append(f"{sizes[fam][k]:g}: {sum(v)}/{len(v)}" if v else f"{sizes[fam][k]:g}: -")
        print(f"{fam:22s} " + " ".join(f"{c:>12s}" for c in cells))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="blind")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per case")
    ap.add_argument("--only", help="comma-separated case-name prefixes, run in this order")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at the same time")
    ap.add_argument("--summary-only", action="store_true", help="print the scores already in the file")
    a = ap.parse_args()
    log = os.path.join(a.bench, "scores.jsonl")
    rows = {}
    if os.path.isfile(log):
        with open(log) as fh:
            for ln in fh:
                if ln.strip():
                    r = json.loads(ln)
                    rows[r["case"]] = r
    names = sorted(d for d in os.listdir(a.bench) if os.path.isfile(os.path.join(a.bench, d, "case.yaml")))
    if a.only:   # in the order given
        names = list(dict.fromkeys(d for p in a.only.split(",") for d in names if d.startswith(p)))
    todo = []
    for name in names:
        if name in rows:
            print(_line(rows[name]), flush=True)
        elif not a.summary_only:
            todo.append(name)
    lock = threading.Lock()

    def one(name):
        folder = os.path.join(a.bench, name)
        code, err, seconds, res = _run(folder, a.timeout)
        with open(os.path.join(folder, "truth.json")) as fh:
            truth = json.load(fh)
        r = score_case(name, truth, code, err, seconds, res, SIZES)
        with lock:  # one whole line per finished case: an interrupted scoring resumes
            with open(log, "a") as fh:
                fh.write(json.dumps(r) + "\n")
            rows[name] = r
            print(_line(r), flush=True)

    with ThreadPoolExecutor(max(1, a.jobs)) as pool:
        list(pool.map(one, todo))
    summary([rows[n] for n in names if n in rows], SIZES)
    return 0


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    sys.exit(main())
