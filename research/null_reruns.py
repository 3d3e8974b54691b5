"""Null and ordinary-change cases of retired blind seeds, rerun with their logs kept.

For each case folder (``BENCH/51_null`` ...) ``diagnose`` is run (``--run``; one process per
case, ``--jobs`` at a time, ``--timeout`` seconds each) into ``OUT/out/<bench>__<case>`` with its
log in ``OUT/<bench>__<case>.log``; cases already done are kept. Then, per case, it prints the
FRF route, the verdict, the baseline reduced chi-square with the spread a right noise model
would give on the same points (``fit.before.reduced_chi2_sd``, :mod:`nlp.diagnosis.spread`) and
how many of those SDs it lies from 1, and the strongest appendage candidate's scaled BIC drop
found in the log (the margin of ``evidence.STRONG_BIC``). Per route: cases inside 0.8-1.3 and
within 2 SDs of 1.

    python research/null_reruns.py --out DIR [--run] BENCH/5[1-9]_* BENCH/6[0-2]_* ...
"""

import argparse
import json
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor

CANDIDATE = re.compile(r"\s+\[\d+\] (\w+) (\{.*?\}|\{\}): score [-\d.e+]+, dBIC ([-\d.e+]+)")
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")


def _name(folder):
    folder = os.path.abspath(folder)
    return f"{os.path.basename(os.path.dirname(folder))}__{os.path.basename(folder)}"


def run_one(folder, out, timeout):
    name = _name(folder)
    dest = os.path.join(out, "out", name)
    if os.path.isfile(os.path.join(dest, "diagnosis.json")):
        return
    with open(os.path.join(out, name + ".log"), "w") as log:
        try:
            subprocess.run([sys.executable, "-m", "nlp", "diagnose",
                            os.path.join(folder, "case.yaml"), "--out", dest, "--workers", "1"],
                           stdout=log, stderr=subprocess.STDOUT, timeout=timeout, cwd=ROOT)
        except subprocess.TimeoutExpired:
            log.write(f"timed out after {timeout} s\n")


def strongest_appendage(log_path):
    best = None
    if os.path.isfile(log_path):
        for line in open(log_path):
            m = CANDIDATE.match(line)
            if m and m.group(1) == "secondary_oscillator":
                d = float(m.group(3))
                best = d if best is None else min(best, d)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+", help="blind case folders (null or ordinary change)")
    ap.add_argument("--out", required=True, help="folder for the logs and diagnoses")
    ap.add_argument("--run", action="store_true", help="run the diagnoses not yet done")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--timeout", type=float, default=900.0)
    a = ap.parse_args()
    os.makedirs(os.path.join(a.out, "out"), exist_ok=True)
    if a.run:
        with ThreadPoolExecutor(a.jobs) as pool:
            list(pool.map(lambda c: run_one(c, a.out, a.timeout), a.cases))
    by_route, strongest = {}, []
    for folder in a.cases:
        name = _name(folder)
        truth = json.load(open(os.path.join(folder, "truth.json")))
        path = os.path.join(a.out, "out", name, "diagnosis.json")
        best = strongest_appendage(os.path.join(a.out, name + ".log"))
        if best is not None:
            strongest.append((best, name))
        if not os.path.isfile(path):
            print(f"{name:36s} {truth['route']:12s} no result (timeout or error)")
            continue
        d = json.load(open(path))
        b = d["fit"]["before"]
        chi, sd = b["reduced_chi2"], b.get("reduced_chi2_sd")
        off = (chi - 1) / sd if sd else float("nan")
        by_route.setdefault(truth["route"], []).append((chi, sd))
        print(f"{name:36s} {truth['route']:12s} {d['verdict']:15s} reduced chi-square {chi:.2f} "
              f"+- {sd:.2f} ({off:+.1f} SD); strongest appendage dBIC "
              f"{'-' if best is None else f'{best:.1f}'}")
    for route, v in by_route.items():
        inside = sum(0.8 <= c <= 1.3 for c, _ in v)
        near = sum(abs(c - 1) <= 2 * s for c, s in v if s)
        print(f"{route:12s} {len(v):2d} cases: {inside} inside 0.8-1.3, {near} within 2 SDs of 1")
    if strongest:
        d, name = min(strongest)
        print(f"strongest appendage candidate over the cases: dBIC {d:.1f} ({name})")


if __name__ == "__main__":
    main()
