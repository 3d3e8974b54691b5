"""Score `frf-nlp diagnose` on the planted real-data cases (scripts/make_planted_real.py).

    nice python scripts/score_planted_real.py --bench /work/planted [--timeout 1800] [--summary-only]

Each case runs as its own `python -m nlp diagnose CASE/case.yaml --out CASE/diagnosis`
subprocess with a time limit, one at a time (the log goes to CASE/diagnose.log). One
JSON line per finished case is appended to BENCH/scores.jsonl, so an interrupted
scoring resumes where it stopped (delete a line to run that case again). Order: the
controls, then the first case of each family per file, then the second ones (so a
partial scoring covers every family), then the controls with the validation file kept.

Scoring: the new findings of a planted case are its findings whose (family, location)
is not among the findings of its file's control (the same data unplanted, the same
case treatment); a hit is a new finding with the planted family at the planted
location (floor, or channel). A planted effect whose family and location the control
already finds cannot be new: it is marked "in control" and its fitted value is shown.
Controls: control_ref (validation file kept, as in the reference run) is compared
finding by finding with the reference diagnosis (--ref-exp, --ref-t2). The joint set of
scripts/make_planted_joint.py (tag `joint`: both tests planted, diagnosed jointly) is
scored the same way against its own control.
"""

import argparse
import json
import os
import subprocess
import sys
import time
from collections import defaultdict

ORDER = ("control", "appendage1", "gain1", "delay1", "mass1", "appendage2", "gain2", "delay2",
         "mass2", "control_ref")
SHORT = {"secondary_oscillator": "appendage", "added_mass": "mass", "sensor_gain": "gain",
         "sensor_delay": "delay", "nonadjacent_coupling": "k", "base_flexibility": "base",
         "hysteretic_damping": "eta", "local_damper": "c", "nonlinearity": "nonlin"}
REF = {"exp": "/work/ref/before/diag_cristallo/diagnosis.json",
       "t2": "/work/ref/before/diag_cristallo2/diagnosis.json"}


def key(f):
    """(family, location) of a finding or a truth, comparable across runs."""
    loc = dict(f["location"] or {})
    if "between" in loc:
        loc["between"] = sorted(loc["between"])
    return (f.get("physics", f.get("family")), json.dumps(loc, sort_keys=True))


def label(f):
    loc = f["location"] or {}
    where = "-".join(map(str, loc["between"])) if "between" in loc else \
        str(loc.get("floor", loc.get("channel", "")))
    vals = ",".join(f"{v:.3g}" for v in (f.get("parameters") or {}).values())
    return f"{SHORT.get(f['physics'], f['physics'])}@{where}" + (f"({vals})" if vals else "")


def run(folder, timeout):
    """Diagnose one case in its own process: (exit code, last error line, seconds, result)."""
    out = os.path.join(folder, "diagnosis")
    cmd = [sys.executable, "-m", "nlp", "diagnose", os.path.join(folder, "case.yaml"), "--out", out]
    t0 = time.perf_counter()
    with open(os.path.join(folder, "diagnose.log"), "w") as log:
        try:
            code = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, timeout=timeout).returncode
        except subprocess.TimeoutExpired:
            code = "timeout"
    seconds = time.perf_counter() - t0
    path = os.path.join(out, "diagnosis.json")
    res = None
    if code == 0 and os.path.isfile(path):
        with open(path) as fh:
            res = json.load(fh)
    return code, seconds, res


def record(name, folder, code, seconds, res):
    with open(os.path.join(folder, "truth.json")) as fh:
        truth = json.load(fh)
    fit = (res or {}).get("fit", {})
    return {"case": name, "truth": truth, "exit": code, "seconds": round(seconds, 1),
            "verdict": (res or {}).get("verdict"),
            "findings": [{k: f[k] for k in ("physics", "location", "parameters", "uncertainty")}
                         for f in (res or {}).get("findings", [])],
            "alternatives": [a.get("physics") for a in (res or {}).get("alternatives", [])
                             if isinstance(a, dict)],
            "chi2_before": fit.get("before", {}).get("reduced_chi2"),
            "chi2_after": fit.get("after", {}).get("reduced_chi2")}


def score(r, control):
    """The case's new findings against its control, and whether the planted effect is one."""
    t = r["truth"]
    base = {key(f) for f in control["findings"]} if control else set()
    new = [f for f in r["findings"] if key(f) not in base]
    want = key(t) if t["family"] else None
    hit = want is not None and any(key(f) == want for f in new)
    in_control = want is not None and want in base
    return new, hit, in_control


def planted_text(t):
    if not t["family"]:
        return "none"
    s, loc = t["size"], t["location"]
    where = loc.get("floor", loc.get("channel"))
    if t["family"] == "secondary_oscillator":
        return (f"appendage@{where} {100 * s['fraction_of_total_mass']:.1f}% "
                f"{s['f_a_hz']:.2f}Hz z{100 * s['zeta_a']:.1f}%")
    if t["family"] == "added_mass":
        return f"mass@{where} {s['dm_kg']:.2f}kg ({100 * s['fraction_of_floor']:.0f}%)"
    if t["family"] == "sensor_gain":
        return f"gain@{where} x{s['gain']:.3f}"
    return f"delay@{where} {s['delay_ms']:.2f}ms"


def compare_ref(r, ref_path):
    """Whether a control's findings repeat the reference's: 'same' or what differs."""
    if not os.path.isfile(ref_path):
        return "no reference diagnosis at this path on this machine: not compared"
    with open(ref_path) as fh:
        ref = json.load(fh)["findings"]
    a = {key(f): f["parameters"] for f in r["findings"]}
    b = {key(f): f["parameters"] for f in ref}
    if set(a) != set(b):
        return (f"differ: here {sorted(label(f) for f in r['findings'])}, "
                f"reference {sorted(label(f) for f in ref)}")
    dev = max((abs(a[k][p] - b[k][p]) / max(abs(b[k][p]), 1e-300) for k in b for p in b[k]),
              default=0.0)
    return f"same findings ({len(b)}), largest relative parameter difference {dev:.1e}"


def table(rows):
    """Print the per-case table, the control checks and the totals per family."""
    controls = {r["case"].split("_")[0]: r for r in rows.values()
                if r["case"].endswith("_control") and r["exit"] == 0}
    print(f"{'case':18s} {'planted':34s} {'named (new findings)':44s} {'hit':8s} "
          f"{'verdict':16s} {'s':>5s}")
    tot = defaultdict(lambda: [0, 0, 0])          # family -> [hits, scored, in control]
    changed = 0
    for name, r in rows.items():
        tag, t = name.split("_")[0], r["truth"]
        if r["exit"] != 0:
            print(f"{name:18s} {planted_text(t):34s} {'(no result: exit ' + str(r['exit']) + ')':44s}")
            continue
        if not t["family"]:
            named = ", ".join(label(f) for f in r["findings"]) or "-"
            print(f"{name:18s} {'none':34s} {'all: ' + named:44s} {'':8s} {r['verdict']:16s} "
                  f"{r['seconds']:5.0f}")
            continue
        ctl = controls.get(tag)
        if ctl is None:
            print(f"{name:18s} {planted_text(t):34s} {'(its control has no result yet)':44s}")
            continue
        new, hit, in_control = score(r, ctl)
        changed += {key(f) for f in r["findings"]} != {key(f) for f in ctl["findings"]}
        here = [f for f in r["findings"] if key(f) == key(t)]
        mark = "hit" if hit else ("in ctl" if in_control and here else "miss")

        tot[t["family"]][0] += hit
        tot[t["family"]][1] += 1
        tot[t["family"]][2] += in_control
        named = ", ".join(label(f) for f in new) or "-"
        if in_control:     # the planted family and location were a control finding already
            named += "; " + ("in control too: " + label(here[0]) if here else "control had: "
                             + label(next(f for f in ctl["findings"] if key(f) == key(t))))
        print(f"{name:18s} {planted_text(t):34s} {named:44s} {mark:8s} {r['verdict']:16s} "
              f"{r['seconds']:5.0f}")
    print("\ncontrols against the reference diagnoses (control: no validation file, as the planted "
          "cases; control_ref: validation file kept, as the reference run):")
    for tag, path in REF.items():
        for suffix in ("control", "control_ref"):
            r = rows.get(f"{tag}_{suffix}")
            if r and r["exit"] == 0:
                print(f"  {tag}_{suffix:12s} vs {path}: {compare_ref(r, path)}")
    print("\ntotals (hit: the planted family at its location among the new findings):")
    for fam in ("secondary_oscillator", "sensor_gain", "sensor_delay", "added_mass"):
        h, n, c = tot[fam]
        print(f"  {fam:21s} {h}/{n}" + (f" ({c} where the control already had that family and location)"
                                        if c else ""))
    core = [tot[f] for f in ("secondary_oscillator", "sensor_gain", "sensor_delay")]
    h, n = sum(x[0] for x in core), sum(x[1] for x in core)
    print(f"  gains, delays and appendages: {h}/{n}" + (f" ({100 * h / n:.0f} %)" if n else ""))
    print(f"  planted cases whose findings differ from their control's: {changed}/"
          f"{sum(x[1] for x in tot.values())}")


def read_scores(log):
    """case -> row of the scores file (empty when there is none yet)."""
    if not os.path.isfile(log):
        return {}
    with open(log) as fh:
        return {r["case"]: r for r in map(json.loads, filter(str.strip, fh))}


def order(bench):
    with open(os.path.join(bench, "manifest.json")) as fh:
        names = json.load(fh)["cases"]
    rank = {s: i for i, s in enumerate(ORDER)}
    return sorted(names, key=lambda n: (rank[n.split("_", 1)[1]], n))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default="planted_real", help="folder of make_planted_real.py")
    ap.add_argument("--summary-only", action="store_true", help="print the scores already in the file")
    ap.add_argument("--only", help="comma-separated case names, run in this order")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per case")
    a = ap.parse_args()
    log = os.path.join(a.bench, "scores.jsonl")
    rows = read_scores(log)
    names = a.only.split(",") if a.only else order(a.bench)
    for name in names:
        if name in rows or a.summary_only:
            continue
        folder = os.path.join(a.bench, name)
        code, seconds, res = run(folder, a.timeout)
        r = record(name, folder, code, seconds, res)
        with open(log, "a") as fh:
            fh.write(json.dumps(r) + "\n")
        rows[name] = r
        print(f"{name}: exit {code}, {seconds:.0f} s, verdict {r['verdict']}, findings "
              f"{[label(f) for f in r['findings']] or '-'}", flush=True)
    table({n: rows[n] for n in order(a.bench) if n in rows})


if __name__ == "__main__":
    main()
