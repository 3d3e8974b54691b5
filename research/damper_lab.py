"""Concentrated dampers on lab cases: the damping decomposition of the baseline.

    python research/damper_lab.py CASE [CASE ...]

CASE: a lab case folder (scripts/make_lab_benchmark.py, development seeds only). Each case's
baseline is fitted as `frf-nlp diagnose` fits it (its windows, 20 starts), then the damping
decomposition of `nlp.diagnosis.inside` is made on it: the structured refit (C = a0 M +
story dashpots) with its excess over the general C and the limit it must stay under, and
per story the dashpot's excess over the others' median with its standard error, the ratio
of its c/k to the others', and the lower story damping ratio against STORY_ZETA; then the
stories past those gates and those named, beyond the bias the family's misfit can cause. Prints the
truth's damper (c in N s/m, story) where there is one. A question for the lab's local
dampers (0/6 in the exam of c7f3e29): do the decomposition's gates see them, and which gate
stops them?
"""

import json
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

import numpy as np  # noqa: E402

from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.driver import baseline_stage, points_stage  # noqa: E402
from nlp.diagnosis.inside import _beyond_misfit, dashpot_refit  # noqa: E402
from nlp.diagnosis.priors import DAMPER_RATIO, DAMPER_SE, STORY_ZETA, damper_check  # noqa: E402


def truth_of(path):
    with open(os.path.join(path, "truth.json")) as fh:
        t = json.load(fh)
    out = []
    for e in t.get("effects", []):
        if e["family"] == "local_damper":
            out.append(f"damper story {e['location']['between'][1]} c {e['parameters']['c_Ns_per_m']:.3g}"
                       f" (size {e['size']})")
        else:
            out.append(e["family"])
    return t.get("category"), out


def _quiet(*args, **kwargs):
    pass


def structured_of(path, quiet=_quiet):
    """A lab case's baseline as `frf-nlp diagnose` fits it (its windows, 20 starts) and its
    story-dashpot refit: (case, points, base, state, structured)."""
    cfg = load_case(os.path.join(path, "case.yaml"))
    case = assemble(cfg)
    points = points_stage(cfg, case, 1, (), quiet)
    base = baseline_stage(cfg, case, points, None, quiet)
    state = {"problem": points.base, "z": base.res.z, "chi": base.chi, "current": []}
    return case, points, base, state, dashpot_refit(case, state)


def one(path, quiet=_quiet):
    t0 = time.perf_counter()
    case, points, base, state, st = structured_of(path, quiet)
    cat, truth = truth_of(path)
    name = f"{os.path.basename(os.path.dirname(path.rstrip('/')))}/{os.path.basename(path.rstrip('/'))}"
    print(f"{name} [{cat}] truth {truth or '-'}; baseline chi2/nu {base.chi / base.nu:.2f}; "
          f"{time.perf_counter() - t0:.0f} s")
    print(f"   structured refit: excess {st['excess']:.1f}, limit {st['limit']:.1f} -> "
          f"{'fits' if st['fits'] else 'does not fit'}")
    for label, (pr, z, cov) in (("structured", (st["problem"], st["z"], st["cov"])),):
        if cov is None:
            from nlp.diagnosis.fitting import quasi_se
            cov = quasi_se(pr, z)[1]
            label += " (judged anyway)"
        info, flagged = damper_check(pr, z, cov)
        ex, se = np.array(info["excess"]), np.array(info["excess_se"])
        print(f"   {label}: unexplained {info['unexplained_fraction']:.2g}; pinned "
              f"{info['pinned_stories'] or '-'}")
        print("     excess/SE (> %g):  " % DAMPER_SE + ", ".join(f"{e / max(s, 1e-300):+.1f}" for e, s in zip(ex, se)))
        print("     excess [N s/m]:   " + ", ".join(f"{e:.3g}+-{s:.2g}" for e, s in zip(ex, se)))
        print("     c/k ratio (> %g):  " % DAMPER_RATIO + ", ".join(f"{r:.2f}" for r in info["ratio_to_others"]))
        print("     story zeta lower (> %g): " % STORY_ZETA
              + ", ".join(f"{r:.2f}" for r in info["story_zeta_ratio_lower"]))
        print("     past the gates: " + (", ".join(f"story {d['story']}" for d in flagged) or "none"))
        kept = _beyond_misfit(flagged, st, quiet)
        print(f"     named (beyond 3 + the misfit's bias of {0 if st['fits'] else np.sqrt(max(st['excess'], 0)):.1f} SE): "
              + (", ".join(f"story {d['story']}" for d in kept) or "none"))
    sys.stdout.flush()


if __name__ == "__main__":
    for p in sys.argv[1:]:
        one(p)
