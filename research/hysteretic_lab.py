"""Hysteretic loss on lab cases: is it seen against story dashpots, where a general C hides it?

    python research/hysteretic_lab.py CASE [CASE ...]

CASE: a lab case folder (scripts/make_lab_benchmark.py, development seeds only). A loss
factor eta in one story adds i eta k_s to its dynamic stiffness; a viscous dashpot adds
i w c_s. Within one mode's window the two are the same (c_s = eta k_s / w_r), so a general C,
free per mode, takes a loss up and the diagnosis's hysteretic candidates, refitted on top of
it, read eta within its errors of zero (0 of 6 in the exam of c7f3e29). Story dashpots are one
number per story for every mode, so there a loss is a shape the family lacks: w_r ranges over
a factor 4-8 across the modes of these frames.

For each case: the baseline and the structured refit (C = a0 M + story dashpots, as
nlp.diagnosis.inside makes it), then the structured model plus a loss (global, then each
story) refitted from the structured optimum: its scaled chi-square drop (phi of the
structured refit), eta with its quasi-likelihood standard error, and the bias bound
sqrt(excess) of the structured-plus-loss model against the general C (inside._beyond_misfit).
Log magnitudes only (the case's residual): the diagnosis's loss check adds the phase off
resonance, which these figures leave out (docs/method/diagnosis.md, section 9).
"""

import json
import math
import os
import sys
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

from nlp.case.parameters import dashpot_damping  # noqa: E402
from nlp.diagnosis.families import HystereticDamping  # noqa: E402
from nlp.diagnosis.fitting import best_fit, diagnosis_problem, quasi_se  # noqa: E402

from damper_lab import structured_of  # noqa: E402  (research/, this script's folder)


def truth_of(path):
    with open(os.path.join(path, "truth.json")) as fh:
        t = json.load(fh)
    return t.get("category"), [f"{e['family']} {e.get('location')} {e.get('parameters')}"
                               for e in t.get("effects", [])]

def with_loss(case, state, st, fam):
    """The structured model plus one loss, refitted from the structured optimum."""
    damping, params = dashpot_damping(case)
    pd = diagnosis_problem(case, state["problem"].target, state["current"] + [fam],
                           optimize=False, damping=(damping, params))
    t = pd.theta(pd.params.z0)
    t0 = st["problem"].theta(st["z"])
    t[:t0.size] = t0
    starts = []
    for eta in (0.005, 0.03):
        t[-1] = eta
        starts.append(pd.params.z_from_theta(t.copy()))
    res = best_fit(pd, starts)
    se, _ = quasi_se(pd, res.z)
    return pd, res, float(pd.theta(res.z)[-1]), float(se[-1])


def one(path):
    t0 = time.perf_counter()
    case, points, base, state, st = structured_of(path)
    pr = points.base
    nu = max(pr.n_used - st["problem"].params.n_z, 1)
    phi = max(st["chi2"] / nu, 1.0)
    cat, truth = truth_of(path)
    name = f"{os.path.basename(os.path.dirname(path.rstrip('/')))}/{os.path.basename(path.rstrip('/'))}"
    print(f"{name} [{cat}] truth {truth or '-'}")
    print(f"   general C chi2 {state['chi']:.1f}; story dashpots {st['chi2']:.1f} (scaled excess "
          f"{st['excess']:.1f}, limit {st['limit']:.1f}); phi {phi:.2f}")
    n = case.model.n
    phi_g = max(state["chi"] / max(pr.n_used - pr.params.n_z, 1), 1.0)
    for fam in [HystereticDamping()] + [HystereticDamping(s) for s in range(1, n + 1)]:
        pd, res, eta, se = with_loss(case, state, st, fam)
        chi = 2 * res.f
        drop = (st["chi2"] - chi) / phi
        excess = (chi - state["chi"]) / phi_g
        bias = math.sqrt(max(excess, 0.0))
        where = "global" if fam.story is None else f"story {fam.story}"
        z = eta / max(se, 1e-300)
        print(f"   + loss {where:>8}: drop {drop:8.1f}  eta {eta:.4f} +- {se:.4f} (z {z:5.1f}); "
              f"excess over general C {excess:7.1f} -> bias bound {bias:4.1f}; "
              f"{'STANDS' if z > 3 + bias and drop > 10 + math.log(pr.n_used) else '-'}")
    print(f"   {time.perf_counter() - t0:.0f} s")
    sys.stdout.flush()

if __name__ == "__main__":
    for p in sys.argv[1:]:
        one(p)
