"""How many resonances the planar model lacks, against how many of its own it has in the band.

    python research/missing_modes.py CASE [CASE ...]

CASE: a lab case folder (scripts/make_lab_benchmark.py, development seeds only) or a case
YAML (a real case: `cases/cristallo_three_storey/case.yaml`). Each case's
baseline is fitted as `frf-nlp diagnose` fits it (its windows, 20 starts); then the
resonances it lacks in the fitted band are listed as the model discrepancy stage lists them
(`nlp.diagnosis.discrepancy.extra_modes_in_band`, before any family is asked to explain
one), beside the baseline's own natural frequencies inside that band. A question for the
torsion cases, whose planar model of an eccentric 3-D frame names appendages and added
masses that were never planted: does the count of resonances outside the model class tell
those frames from the others (nulls with the lab's table, in-catalogue effects, frames with
flexible beams, effects outside the catalogue), without asking any family?
"""

import json
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)


from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.discrepancy import extra_modes_in_band, own_modes_in_band  # noqa: E402
from nlp.diagnosis.driver import baseline_stage, points_stage  # noqa: E402


def _quiet(*args, **kwargs):
    pass


def one(path):
    t0 = time.perf_counter()
    cfg = load_case(path if path.endswith(".yaml") else os.path.join(path, "case.yaml"))
    path = os.path.dirname(path) if path.endswith(".yaml") else path
    case = assemble(cfg)
    points = points_stage(cfg, case, 1, (), _quiet)
    base = baseline_stage(cfg, case, points, None, _quiet)
    extra = [m.f0 for m in extra_modes_in_band(case, points, base)]
    own = own_modes_in_band(case, points.base, base.res.z)
    truth = os.path.join(path, "truth.json")
    cat = "-"
    if os.path.exists(truth):      # a real case (Cristallo) has none
        with open(truth) as fh:
            cat = json.load(fh).get("category")
    row = {"case": "/".join(path.rstrip("/").split("/")[-2:]), "category": cat,
           "own": [round(float(f), 3) for f in own], "extra": [round(f, 3) for f in extra],
           "chi2_nu": float(base.chi / base.nu), "seconds": time.perf_counter() - t0}
    print(f"{row['case']:<42} {cat:<17} own {len(own)} extra {len(extra)}  "
          f"chi2/nu {row['chi2_nu']:.1f}  extra at {', '.join(f'{f:.2f}' for f in extra) or '-'}"
          f"  ({row['seconds']:.0f} s)", flush=True)
    return row


def main(paths):
    for p in paths:
        try:
            one(p)
        except Exception as exc:      # a research sweep: report the case and go on
            print(f"{p}: {type(exc).__name__}: {exc}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
