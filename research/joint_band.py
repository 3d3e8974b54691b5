"""The level comparison's materiality rule on two-level lab cases (nlp.diagnosis.materiality).

    python research/joint_band.py [--deltas 0.01,0.02,0.03,0.05] CASE [CASE ...]

CASE: a lab case folder with two levels (scripts/make_lab_benchmark.py, development seeds
only). Per case: the levels' likelihood-ratio excess over one common set of masses and
stiffnesses (levels.shared_stiffness) and its BIC limit, then for each band delta the least
rise of the banded refits (each mass and story stiffness free within +-delta between the
levels), whether it is material and the seconds it took; the decision of
materiality.joint_gate (JOINT_CHANGE, and the level kind when within it); and the truth
(truth.json: the planted effect and the lab's joints, their change between the levels).
"""

import argparse
import json
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.levels import _harmonics, _own_chi2, _phi, level_fit, shared_stiffness  # noqa: E402
from nlp.diagnosis.materiality import banded_change, joint_gate  # noqa: E402
from nlp.diagnosis.others import assemble_other  # noqa: E402


def truth_of(path):
    with open(os.path.join(path, "truth.json")) as fh:
        t = json.load(fh)
    what = t.get("effects") or t.get("outside_effect") or t.get("effect") or "null"
    joints = [f"{100 * ln['change_1_to_3']:+.1f}" for ln in t.get("links", [])
              if "change_1_to_3" in ln]
    return what, joints


def one(path, deltas):
    cfg = load_case(os.path.join(path, "case.yaml"))
    ref = level_fit(cfg, cfg.data.file)
    c, _ = assemble_other(cfg, cfg.data.level_files[0], lambda *a, **k: None)
    lv = level_fit(cfg, cfg.data.level_files[0], ref["z"], c)
    lr = shared_stiffness(ref, lv)
    own = {"ref": _own_chi2(ref), "lv": _own_chi2(lv)}
    phi = {"ref": _phi(ref), "lv": _phi(lv)}
    harm = _harmonics(cfg, [ref, lv])
    located = bool(harm and harm["best"] is not None)
    gate, kind = joint_gate(ref, lv, lr["limit"], own, phi, lambda m: print(m, flush=True))
    gate["harmonics_located"] = located
    rows = []
    for d in deltas:
        t0 = time.perf_counter()
        b = banded_change(ref, lv, lr["limit"], own, phi, delta=d)
        rows.append({**b, "seconds": time.perf_counter() - t0})
    return lr, rows, gate, kind


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--deltas", default="0.01,0.02,0.03,0.05",
                    type=lambda s: [float(x) for x in s.split(",")])
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    for path in a.cases:
        path = path.rstrip("/")
        lr, rows, gate, kind = one(path, a.deltas)
        what, joints = truth_of(path)
        level = "level-dependent" if lr["excess"] > lr["limit"] and lr["converged"] else "linear"
        print(f"{os.path.basename(path):36s} common set +{lr['excess']:.1f} (limit {lr['limit']:.1f}, "
              f"{level}); truth {what}; joints {', '.join(joints)} %", flush=True)
        for r in rows:
            print(f"{'':36s} band +-{100 * r['delta']:.0f} %: +{r['excess']:.1f} "
                  f"({r['way']}; rises {', '.join(f'{k} {v:.1f}' for k, v in r['rises'].items())}; "
                  f"converged {r['converged']}) -> "
                  f"{'material' if r['material'] else 'within' if r['within'] else 'not decided'} "
                  f"({r['seconds']:.0f} s)", flush=True)
        k = "-" if kind is None else f"{kind['kind']} at {kind['index'] + 1}, rises {kind['rises']}"
        print(f"{'':36s} the rule: {'a finding' if gate['finding'] else 'not a finding'} (kind {k}; "
              f"harmonics {'locate one story' if gate['harmonics_located'] else 'locate none'})",
              flush=True)
        print(json.dumps({"case": path, "shared": lr, "bands": rows, "truth": what, "gate": gate,
                          "joints": joints}, default=str), file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
