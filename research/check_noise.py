"""Reduced chi-square of null cases on every FRF route (the noise model's check).

    python research/check_noise.py [--seeds 5]

Each case is a 3-storey frame whose physics is inside the model class
(general damping), simulated by nlp/testing/noise_sim.py independently of the
package (scipy lsim at 10x the recorded rate; 2 % noise on the input and every
output), fitted by the package with residuals weighted by nlp/noise.py. A
correct noise model gives a reduced chi-square near 1 (0.8-1.3) on each route.
"""

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import numpy as np  # noqa: E402

from nlp.testing import noise_sim as sf  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="cases per route (seeds 100, 101, ...)")
    args = ap.parse_args(argv)
    seeds = "".join(f"  seed {100 + s:<4}" for s in range(args.seeds))
    print(f"{'route':<15}{'route found':<15}{seeds}   median   [s/case]")
    for route in sf.ROUTES:
        vals, found, t0 = [], None, time.perf_counter()
        for s in range(args.seeds):
            with tempfile.TemporaryDirectory() as d:
                chi2, model, _ = sf.reduced_chi2(sf.null_case(route, d, seed=100 + s))
            vals.append(chi2)
            found = model.route
        dt = (time.perf_counter() - t0) / args.seeds
        print(f"{route:<15}{found:<15}" + "".join(f"  {v:9.3f}" for v in vals)
              + f"   {np.median(vals):6.3f}   {dt:6.1f}")


if __name__ == "__main__":
    main()
