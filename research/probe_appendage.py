"""Why an appendage was missed: the frequency scan against a refit at a given frequency.

`diagnose` scans a tiny oscillator over the band at each floor (its frequency is a nuisance
parameter) and refits each floor's candidate from the scan's best frequency only. This
script repeats the baseline fit (20 starts, as `diagnose`), prints the scan's best frequency
and score per floor, then refits the appendage at FLOOR from the scan's frequency and from
each frequency given, with chi-square, held-out chi-square, values and quasi-likelihood
standard errors (the numbers `diagnose` judges).

    python research/probe_appendage.py CASE.yaml FLOOR [F_HZ ...]
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import nlp.diagnosis.driver as D  # noqa: E402
from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.families import SecondaryOscillator  # noqa: E402
from nlp.solve.search import SearchConfig  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("floor", type=int)
    ap.add_argument("frequencies", type=float, nargs="*", help="appendage frequencies to refit from [Hz]")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    cfg = load_case(a.case)
    case = assemble(cfg)
    fit = D._windows(cfg, case, 1)
    held = np.setdiff1d(D._windows(cfg, case, 3), fit)
    sig_held = D.noise_sigma(case, held)
    target = D._target(case, fit, D.noise_sigma(case, fit))
    base = D._problem(case, target)
    t0 = time.time()
    res, conv = D._search(base, SearchConfig(starts=max(cfg.search.starts, 20), seed=cfg.search.seed,
                                             workers=a.workers))
    nu = max(base.n_used - base.params.n_z, 1)
    rh = D._normalised(base, res.z, case, held, sig_held)
    print(f"baseline: chi-square {2 * res.f:.1f} (reduced {2 * res.f / nu:.2f}), held-out "
          f"{np.mean(rh ** 2):.2f}, converged {conv}, {time.time() - t0:.0f} s", flush=True)
    scan = D._scan_secondary(case, target, [], res.z)
    for e, (score, _) in scan:
        print(f"scan: floor {e.floor}, best frequency {e.f0:.2f} Hz, score {score:.1f}", flush=True)
    starts = [e.f0 for e, _ in scan if e.floor == a.floor] + list(a.frequencies)
    for f0 in starts:
        r = D._refit(case, target, [], res.z, SecondaryOscillator(a.floor, f0), 0.0, base.n_used,
                     held, sig_held)
        vals = ", ".join(f"{k} = {v:.4g} +- {r['uncertainty'][k]:.2g}" for k, v in r["parameters"].items())
        print(f"refit from {f0:.2f} Hz: chi-square {r['chi2']:.1f}, held-out {r['held_out']:.2f}, "
              f"{vals}, converged {r['converged']}", flush=True)


if __name__ == "__main__":
    main()
