"""Every stored held-back scoring of the blind benchmark, one line each, against issue 7's targets.

Reads ``docs/benchmarks/blind_SEED_scores.jsonl`` (written by scripts/score_blind.py) in the
order of the README's "Retired seeds" list, and prints per seed: cases scored, correct family
and location over the detectable effects (size rank >= 2), false alarms (null and ordinary
cases not ``adequate``), the median held-out ratio where the right physics was accepted, and
per FRF route the range of the baseline reduced chi-square of the null and ordinary cases,
starred where a case falls outside 0.8-1.3. A pooled line closes the table.

    python research/scoring_history.py [--from SEED]
"""

import argparse
import json
import re
from pathlib import Path

import numpy as np

from nlp.testing.blind.structures import SIZE_DETECTABLE

ROOT = Path(__file__).resolve().parents[1]
ROUTES = ("one_segment", "welch", "frf_file")
BAND = (0.8, 1.3)  # the baseline target of issue 7


def seeds_in_order():
    text = (ROOT / "README.md").read_text()
    m = re.findall(r"Retired seeds:((?:\s*\d+,?)+)", text)
    listed = [s for s in re.findall(r"\d+", m[-1])] if m else []
    stored = {p.name.split("_")[1] for p in (ROOT / "docs/benchmarks").glob("blind_*_scores.jsonl")}
    return [s for s in listed if s in stored] + sorted(stored - set(listed))


def row(seed):
    rows = [json.loads(line) for line in
            (ROOT / f"docs/benchmarks/blind_{seed}_scores.jsonl").read_text().splitlines() if line]
    det = [e for r in rows for e in r["effects"] if e.get("rank", 3) >= SIZE_DETECTABLE]
    quiet = [r for r in rows if r["kind"] != "effect"]
    held = [r["held_out_ratio"] for r in rows if r["kind"] == "effect" and r["held_out_ratio"]
            and any(e["location_ok"] for e in r["effects"])]
    base = {}
    for route in ROUTES:
        v = [r["baseline_reduced_chi2"] for r in quiet
             if r["route"] == route and r["baseline_reduced_chi2"] is not None]
        base[route] = v
    return {"seed": seed, "n": len(rows), "det": (sum(e["location_ok"] for e in det), len(det)),
            "fa": (sum(r["verdict"] != "adequate" for r in quiet), len(quiet)),
            "held": float(np.median(held)) if held else None, "base": base}


def fmt_base(v):
    if not v:
        return "-"
    out = any(x < BAND[0] or x > BAND[1] for x in v)
    return f"{min(v):.2f}-{max(v):.2f}{'*' if out else ''}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="start", help="first seed to list (README order)")
    a = ap.parse_args(argv)
    seeds = seeds_in_order()
    if a.start:
        seeds = seeds[seeds.index(a.start):]
    print(f"{'seed':>7s} {'cases':>5s} {'detectable':>12s} {'false al.':>9s} {'held-out':>8s}  "
          + "  ".join(f"{r:>14s}" for r in ROUTES))
    tot = {"det": [0, 0], "fa": [0, 0], "base": {r: [] for r in ROUTES}}
    for s in seeds:
        r = row(s)
        d, f = r["det"], r["fa"]
        held = "-" if r["held"] is None else f"{r['held']:.3f}"
        print(f"{s:>7s} {r['n']:5d} {d[0]:4d}/{d[1]:<3d}{100 * d[0] / max(d[1], 1):3.0f}% "
              f"{f[0]:3d}/{f[1]:<3d}  {held:>8s}  "
              + "  ".join(f"{fmt_base(r['base'][k]):>14s}" for k in ROUTES))
        for k in ("det", "fa"):
            tot[k][0] += r[k][0]
            tot[k][1] += r[k][1]
        for k in ROUTES:
            tot["base"][k] += r["base"][k]
    d, f = tot["det"], tot["fa"]
    print(f"{'pooled':>7s} {'':5s} {d[0]:4d}/{d[1]:<3d}{100 * d[0] / max(d[1], 1):3.0f}% "
          f"{f[0]:3d}/{f[1]:<3d}  {'':>8s}  "
          + "  ".join(f"{sum(BAND[0] <= x <= BAND[1] for x in v):>6d}/{len(v):<3d} in" .rjust(14)
                      for v in tot["base"].values()))
    print("* a case outside 0.8-1.3; the pooled line counts the cases inside it")


if __name__ == "__main__":
    main()
