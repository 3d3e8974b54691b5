"""Phase check for sensor delays on blind-benchmark cases, from a quick baseline fit.

For each case folder (case.yaml + truth.json): the log-magnitude baseline of
`frf-nlp diagnose` (6 starts), then nlp.diagnosis.phase.delay_check on the
fitted and held-out points. Prints each channel's delay, its quasi-likelihood
standard error, the scaled BIC change, the fraction of the phase chi-square it
explains and its phase at the top of the band (*** = significant), then the
findings next to the truth.

    python research/phase_delays_blind.py BENCH/36_sensor_delay BENCH/51_null ...
"""

import json
import os
import sys
import time

import numpy as np

from nlp.diagnosis import driver as D
from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.phase import delay_check
from nlp.solve.search import SearchConfig


def main(paths):
    for path in paths:
        t0 = time.time()
        cfg = load_case(os.path.join(path, "case.yaml"))
        case = assemble(cfg)
        fit = D._windows(cfg, case, 1)
        held = np.setdiff1d(D._windows(cfg, case, 3), fit)
        base = D._problem(case, D._target(case, fit, D.noise_sigma(case, fit)))
        res, _ = D._search(base, SearchConfig(starts=6, seed=1))
        idx = np.union1d(fit, held)
        Ha = base.channel_frfs(res.z, 2 * np.pi * case.f[idx])
        out = delay_check(case.f[idx], case.H[:, idx], Ha, case.noise.sigma_phase[:, idx],
                          [c.name for c in case.channels])
        truth = json.load(open(os.path.join(path, "truth.json")))
        nu = max(base.n_used - base.params.n_z, 1)
        print(f"{os.path.basename(path)}  baseline chi2/nu {2 * res.f / nu:.2f}  "
              f"{time.time() - t0:.0f} s  truth "
              f"{[(e['family'], e['location'], e['parameters']) for e in truth['effects']]}")
        for r in out["channels"]:
            print(f"   {r['channel']:<5} tau {r['delay_ms']:8.3f} ms  se {r['standard_error_ms']:.3f}  "
                  f"dBIC {r['delta_bic']:11.1f}  explained {r['explained']:.3f}  "
                  f"phase at fmax {1e-3 * r['delay_ms'] * r['omega_max']:6.2f} rad"
                  f"{'  ***' if r['significant'] else ''}")
        print("   findings:", [(f["location"]["channel"], round(next(iter(f["parameters"].values())), 3))
                               for f in out["findings"]])


if __name__ == "__main__":
    main(sys.argv[1:])
