"""Time the discrepancy stage's restriction refits with and without the box starts.

    python research/discrepancy_starts.py CASE.yaml [CASE.yaml ...] [--only new]

For each case: the diagnosis's baseline, the resonances the model lacks, the model with a
free modal term at each (as `frf-nlp diagnose` fits them), then for each resonance the
catalogue refits of `nlp.diagnosis.discrepancy.explained_by` started only at the resonance
(box=False, what diagnose does) and also from refit's two seeded box starts (box=True,
before 2026-11-29): seconds, each candidate's scaled chi-square rise over the free term and
its limit, and the decision (left to the candidate search, or kept as model discrepancy).
"""

import argparse
import time

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.discrepancy import (explained_by, extra_modes_in_band, fit_discrepancy,
                                       resonant)
from nlp.diagnosis.driver import baseline_stage, points_stage
from nlp.diagnosis.fitting import best_fit
from nlp.diagnosis.decide import where
from nlp.solve.executors.threads import limit_blas_threads


def quiet(*a, **k):
    pass


def free_terms(path):
    """(case, the look's points with windows at the resonances, the modes, the model with a
    free term at each and its optimum), or None when the baseline lacks no resonance: the
    discrepancy stage's inputs, as `frf-nlp diagnose` computes them (printed as it goes)."""
    cfg = load_case(path)
    case = assemble(cfg)
    t0 = time.perf_counter()
    points = points_stage(cfg, case, 1, (), quiet)
    base = baseline_stage(cfg, case, points, None, quiet)
    modes = extra_modes_in_band(case, points, base)
    print(f"{path}: baseline {time.perf_counter() - t0:.0f} s; resonances the model lacks: "
          + (", ".join(f"{m.f0:.2f} Hz" for m in modes) or "none"), flush=True)
    if not modes:
        return None
    wide = points_stage(cfg, case, 1, tuple(m.f0 for m in modes), quiet)
    t0 = time.perf_counter()
    b0 = best_fit(wide.base, [base.res.z])
    pr_d, res_d = fit_discrepancy(case, wide.base, b0.z, modes, wide.fit)
    print(f"  free modal terms fitted in {time.perf_counter() - t0:.0f} s: chi-square "
          f"{2 * res_d.f:.1f}", flush=True)
    return case, wide, modes, pr_d, res_d


def one(path, variants):
    got = free_terms(path)
    if got is None:
        return
    case, wide, modes, pr_d, res_d = got
    measured = resonant(pr_d, res_d.z, modes)
    for m in modes:
        if not any(m is x for x in measured):
            print(f"  {m.f0:.2f} Hz: damping at its bound (not a resonance)")
            continue
        for box in variants:
            t0 = time.perf_counter()
            alts = explained_by(case, wide.target, pr_d, res_d, modes, m, wide.base.n_used,
                                wide.held, wide.sig_held, box=box)
            dt = time.perf_counter() - t0
            said = (f"left to the search ({where(alts[0])}, rise "
                    f"{alts[0]['restriction']['scaled_rise']:.1f} <= "
                    f"{alts[0]['restriction']['limit']:.1f})") if alts else "kept as discrepancy"
            print(f"  {m.f0:.2f} Hz, box={box}: {dt:.0f} s, {said}", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+")
    ap.add_argument("--only", choices=("new", "both"), default="both")
    a = ap.parse_args()
    limit_blas_threads()
    for path in a.cases:
        one(path, (False,) if a.only == "new" else (False, True))


if __name__ == "__main__":
    main()
