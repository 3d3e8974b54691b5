"""How the scatter level of an FRF file without coherence compares with its coherence, at the truth.

For each seed's pair of null files written by ``research/frf_file_coherence_control.py``
(``DIR/SEED/62_null_frf`` and ``DIR/SEED/coherent``: the same H, with and without the stored
coherence), the mean of z^2 = ln|H / H_t|^2 / sigma^2 over the points that ``diagnose`` fits
is printed with sigma from:

* ``coherence``: the coherence variance of the ``coherent`` file (the noise measured from the
  records);
* ``package``: the file's own scatter as the package reads it (``nlp.frf.noise.spaced_scatter``,
  the robust level over 2 x 25 + 1 differences);
* variants of that level, not in the package: half-widths 12 and 50; a trimmed mean of the
  squared differences (20 %, 30 % trimmed) in place of the median absolute deviation; one level
  for ln|H| and arg H together (both parts' differences in one median); the level of the
  differences times |H| at their centre, divided by |H| again (the output-noise shape
  1 / |H|^2); and the level without the differences whose span holds a sharp feature (a
  squared resolution bias over (k x the package's level)^2, k = 2 and 4), so that the
  structure's peaks do not count as scatter.

H_t is the true FRF (``truth.json``, computed in ``research/noise_at_truth.py`` independently of
the package's FRF code) through the Hann window's three taps, as the fit sees it. A column's
per-file values spread by sampling as well as by the level; the last lines give each column's
mean, SD, files outside 0.8-1.3, and the SD of ln(column / coherence): the level's own error.

    python research/frf_file_scatter_variants.py --dir DIR [SEED ...]   (default: every seed in DIR)
"""

import argparse
import json
import math
import os
import sys
from types import SimpleNamespace
from unittest import mock

import numpy as np
from scipy.ndimage import maximum_filter1d
from scipy.stats import norm

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)

from noise_at_truth import _At, true_frf  # noqa: E402
from nlp.frf import noise as N  # noqa: E402
from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.fitting import _windows  # noqa: E402

PACKAGE = N._robust_levels


def taps_truth(truth, case):
    """The true FRF through the estimate's three taps (what the fit compares with)."""
    h, a = case.target.kernel
    df = h / (2 * np.pi)
    return sum(c * true_frf(truth, _At(case, case.f + s * df))
               for s, c in ((-1, a), (0, 1 - 2 * a), (1, a)))


def _windowed(d, n, shift, half_width, stat):
    """stat(segment) per point over 2 half_width + 1 differences, as the package's levels."""
    s = np.empty((d.shape[0], n))
    for k in range(n):
        j = min(max(k - shift, 0), d.shape[1] - 1)
        s[:, k] = stat(d[:, max(j - half_width, 0):j + half_width + 1])
    return s


def half_width(scale):
    return lambda d, n, shift, hw, factor: PACKAGE(d, n, shift, int(hw * scale), factor)


def trimmed(trim):
    q = norm.ppf(1 - trim / 2)
    c = 1 - 2 * q * norm.pdf(q) / (1 - trim)     # E[x^2 | |x| < q], standard normal

    def stat(seg):
        a = np.sort((seg - np.median(seg, axis=1, keepdims=True)) ** 2, axis=1)
        return a[:, :max(int(round(a.shape[1] * (1 - trim))), 1)].mean(axis=1) / c

    def levels(d, n, shift, hw, factor):
        return tuple(np.maximum(np.sqrt(_windowed(p, n, shift, hw, stat) / factor), 1e-4)
                     for p in (d.real, d.imag))
    return levels


def pooled(d, n, shift, hw, factor):
    """One median absolute deviation over the real and imaginary differences together."""
    both = np.concatenate([d.real - np.median(d.real, axis=1, keepdims=True),
                           d.imag - np.median(d.imag, axis=1, keepdims=True)], axis=1)
    m = d.shape[1]
    s = np.empty((d.shape[0], n))
    for k in range(n):
        j = min(max(k - shift, 0), m - 1)
        lo, hi = max(j - hw, 0), j + hw + 1
        s[:, k] = np.median(np.abs(np.concatenate([both[:, lo:hi], both[:, m + lo:m + hi]],
                                                  axis=1)), axis=1)
    s = np.maximum(1.4826 * s / math.sqrt(factor), 1e-4)
    return s, s.copy()


def output_shape(H):
    mag = np.abs(H)

    def levels(d, n, shift, hw, factor):
        off = (n - d.shape[1]) // 2
        a, b = PACKAGE(d * mag[:, off:off + d.shape[1]], n, shift, hw, factor)
        return a / np.maximum(mag, 1e-300), b / np.maximum(mag, 1e-300)
    return levels


def without_sharp(H, k):
    bias2 = N._file_resolution_bias2(np.arange(H.shape[1], dtype=float), H, "hann")

    def levels(d, n, shift, hw, factor):
        first = PACKAGE(d, n, shift, hw, factor)
        m = d.shape[1]
        # the largest bias over each difference's span of 3 x 3 + 1 bins
        over = maximum_filter1d(bias2, size=10, axis=1, mode="nearest")[:, shift:shift + m]
        out = []
        for part, s1 in zip((d.real, d.imag), first):
            sharp = over > (k * s1[:, shift:shift + m]) ** 2
            s = s1.copy()
            for k_ in range(n):
                j = min(max(k_ - shift, 0), m - 1)
                lo, hi = max(j - hw, 0), j + hw + 1
                for c in range(d.shape[0]):
                    seg = part[c, lo:hi][~sharp[c, lo:hi]]
                    if seg.size >= 15:
                        s[c, k_] = 1.4826 * np.median(np.abs(seg - np.median(seg))) / math.sqrt(factor)
            out.append(np.maximum(s, 1e-4))
        return tuple(out)
    return levels


def variants(H):
    return {"package": PACKAGE, "hw12": half_width(0.5), "hw50": half_width(2.0),
            "trim20": trimmed(0.2), "trim30": trimmed(0.3), "re+im": pooled,
            "1/|H|": output_shape(H), "sharp2": without_sharp(H, 2.0),
            "sharp4": without_sharp(H, 4.0)}


def one_seed(folder):
    case = assemble(load_case(os.path.join(folder, "62_null_frf", "case.yaml")))
    coherent = assemble(load_case(os.path.join(folder, "coherent", "case.yaml")))
    assert case.noise.route == "scatter" and np.array_equal(case.H, coherent.H)
    truth = json.load(open(os.path.join(folder, "coherent", "truth.json")))
    fit = _windows(case.config, case, 1)
    e2 = np.log(np.abs(case.H / taps_truth(truth, case)))[:, fit] ** 2
    row = {"coherence": np.mean(e2 / coherent.noise.sigma_ln[:, fit] ** 2)}
    bare = SimpleNamespace(records=None, config=case.config, f=case.f, H=case.H, coherence=None,
                           n_averages=None, kernel=case.target.kernel)
    for name, levels in variants(case.H).items():
        with mock.patch.object(N, "_robust_levels", levels):
            row[name] = np.mean(e2 / N.noise_model(bare).sigma_ln[:, fit] ** 2)
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", required=True, help="the --out folder of frf_file_coherence_control")
    ap.add_argument("seeds", nargs="*")
    a = ap.parse_args()
    seeds = a.seeds or sorted(s for s in os.listdir(a.dir)
                              if os.path.isdir(os.path.join(a.dir, s, "coherent")))
    rows = []
    for s in seeds:
        rows.append(one_seed(os.path.join(a.dir, s)))
        if len(rows) == 1:
            print(f"{'seed':>8} " + " ".join(f"{k:>9}" for k in rows[0]))
        print(f"{s:>8} " + " ".join(f"{v:9.2f}" for v in rows[-1].values()), flush=True)
    coh = np.array([r["coherence"] for r in rows])
    print(f"mean z^2 at the truth on the fitted points of {len(rows)} files:")
    for k in rows[0]:
        v = np.array([r[k] for r in rows])
        print(f"  {k:>9}: mean {v.mean():.2f}, SD {v.std(ddof=1):.2f}, outside 0.8-1.3: "
              f"{int(np.sum((v < 0.8) | (v > 1.3)))}, SD of ln(/coherence) "
              f"{np.std(np.log(v / coh), ddof=1):.2f}")


if __name__ == "__main__":
    main()
