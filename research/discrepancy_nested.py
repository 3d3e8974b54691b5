"""Does the family that "explains" a resonance the model lacks leave its free term unneeded?

    python research/discrepancy_nested.py CASE.yaml [CASE.yaml ...]

The discrepancy stage (nlp.diagnosis.discrepancy.explained_by) compares two models that are
not nested: the other resonances' free terms plus a catalogue family X, against every
resonance's free term. A family that also fits misfit elsewhere (a flexible base moves every
mode) can beat the free terms at a resonance it does not produce. The nested question is
whether, with X in the model, resonance e's free term still lowers the chi-square: for each
family the stage lets pass, this script fits X + every free term, started from X's refit
(continued uncapped) with e's term at its free-fit values and with its residues at zero (the
latter starts exactly at X's chi-square), and prints both scaled rises and their limits
(docs/method/diagnosis.md, section 10b, 2026-12-07).
"""

import argparse
import os
import sys
import time
from dataclasses import replace

import numpy as np
from scipy.stats import chi2 as chi2_dist

from nlp.diagnosis.decide import where
from nlp.diagnosis.discrepancy import RESTRICTION_LEVEL, explained_by, resonant
from nlp.diagnosis.evidence import dispersion
from nlp.diagnosis.fitting import best_fit, diagnosis_problem
from nlp.solve.executors.threads import limit_blas_threads

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from discrepancy_starts import free_terms  # noqa: E402  (the stage's inputs, computed alike)


def term_theta(pr_d, z_d, modes, e):
    """Mode e's physical parameters in the model with every mode (pr_d at z_d)."""
    th = pr_d.theta(z_d)
    k = th.size - sum(len(m.names) for m in modes)
    for m in modes:
        if m is e:
            return th[k:k + len(m.names)]
        k += len(m.names)
    raise ValueError("mode not in modes")


def nested(case, target, pr_d, res_d, modes, e, r):
    """(X's chi-square continued uncapped, X + e's chi-square, its status) for refit r."""
    others = tuple(m for m in modes if m is not e)
    X = r["enrichment"]
    k = len(X.names)
    pr_x = diagnosis_problem(replace(case, discrepancy=others), target, [X], optimize=False)
    rx = pr_x.solve(r["z"])
    chi_x = min(2 * rx.f, r["chi2"])
    th_x = pr_x.theta(rx.z if 2 * rx.f <= r["chi2"] else r["z"])
    pr_n = diagnosis_problem(replace(case, discrepancy=others + (e,)), target, [X], optimize=False)
    th_e = np.array(term_theta(pr_d, res_d.z, modes, e), float)
    th_0 = np.concatenate([th_e[:2], np.zeros(th_e.size - 2)])   # residues a_c at zero
    starts = [pr_n.params.z_from_theta(np.concatenate([th_x[:-k], t, th_x[-k:]]))
              for t in (th_e, th_0)]
    rn = best_fit(pr_n, starts)
    return chi_x, 2 * rn.f, rn.status


def one(path):
    got = free_terms(path)
    if got is None:
        return
    case, wide, modes, pr_d, res_d = got
    phi = dispersion(2 * res_d.f, wide.base.n_used - pr_d.params.n_z)
    print(f"  phi {phi:.2f}", flush=True)
    measured = resonant(pr_d, res_d.z, modes)
    for e in modes:
        if not any(e is x for x in measured):
            print(f"  {e.f0:.2f} Hz: damping at its bound (not a resonance)")
            continue
        t0 = time.perf_counter()
        alts = explained_by(case, wide.target, pr_d, res_d, modes, e, wide.base.n_used,
                            wide.held, wide.sig_held)
        if not alts:
            print(f"  {e.f0:.2f} Hz: kept as discrepancy by the stage ({time.perf_counter() - t0:.0f} s)")
            continue
        lim_n = chi2_dist.ppf(RESTRICTION_LEVEL, len(e.names))
        for r in alts:
            chi_x, chi_n, status = nested(case, wide.target, pr_d, res_d, modes, e, r)
            rise_n = (chi_x - chi_n) / phi
            print(f"  {e.f0:.2f} Hz, {where(r)}: stage rise {r['restriction']['scaled_rise']:.1f} "
                  f"(limit {r['restriction']['limit']:.1f}); with it in the model, the free term "
                  f"still gains {rise_n:.1f} (limit {lim_n:.1f}; X {chi_x:.1f} -> X + term "
                  f"{chi_n:.1f}, {status}) -> "
                  + ("explained" if rise_n <= lim_n else "NOT explained")
                  + f" [{time.perf_counter() - t0:.0f} s]", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    limit_blas_threads()
    for path in a.cases:
        one(path)


if __name__ == "__main__":
    main()
