"""Sampling spread of a Welch case's mean z^2 at the true structure.

    python research/welch_spread.py [--seeds 12] [--seconds 400] [--zeta 0.015]

The 3-storey frame of nlp/testing/noise_sim.py (scipy lsim, independent of the package;
Rayleigh damping at zeta, 2 % noise on the input and every output) is driven by
band-limited random input and recorded at 100 Hz; the package estimates H1 by Welch
(Hann, 4096 samples, half overlap) and its noise model. Printed per seed: the mean
z^2 = (ln|H / H_true,3-tap| / sigma)^2 over the points the case fits, H_true seen
through the model's own three taps. Its spread over seeds is what a baseline reduced
chi-square of a correct fit scatters by on such records.
"""

import argparse
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from nlp.testing import noise_sim as ns  # noqa: E402
from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402


def mean_z2(seed, seconds, zeta):
    rng = np.random.default_rng(seed)
    M, _, K = ns.frame()
    w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    a0, a1 = np.linalg.solve([[1 / (2 * w[0]), w[0] / 2], [1 / (2 * w[-1]), w[-1] / 2]],
                             [zeta, zeta])
    C = a0 * M + a1 * K
    u = ns.random_input(ns.FS_FINE, 20.0, seconds, rng)
    x, y = ns.add_noise(*ns.simulate(u, ns.FS_FINE, M, C, K, decim=ns.DECIM), 0.02, rng)
    with tempfile.TemporaryDirectory() as d:
        case = assemble(load_case(ns.records_case(d, x, y, {"nperseg": 4096})))
    h, a = case.target.kernel
    f, dh = case.f, h / (2 * np.pi)
    Hk = (a * ns.frf_exact(M, C, K, f - dh) + (1 - 2 * a) * ns.frf_exact(M, C, K, f)
          + a * ns.frf_exact(M, C, K, f + dh))
    idx = case.selected
    z2 = (np.log(np.abs(case.H[:, idx] / Hk[:, idx])) / case.noise.sigma_ln[:, idx]) ** 2
    return float(z2.mean()), z2.size


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--seconds", type=float, default=400.0)
    ap.add_argument("--zeta", type=float, default=0.015)
    a = ap.parse_args(argv)
    vals = []
    for s in range(a.seeds):
        v, n = mean_z2(s, a.seconds, a.zeta)
        vals.append(v)
        print(f"seed {s:3d}: mean z^2 {v:.3f} on {n} points", flush=True)
    v = np.array(vals)
    print(f"mean {v.mean():.3f}, SD {v.std():.3f}, range {v.min():.2f}-{v.max():.2f}")


if __name__ == "__main__":
    main()
