"""The case's noise model against the true FRF of a blind benchmark case.

For a null or ordinary-change case of ``scripts/make_blind_benchmark.py`` the true
structure is in ``truth.json`` (``system``: M, C, K, Kh). Its FRF is computed here from
those matrices, independently of the package's FRF code:

* ground input a_g: relative coordinates q = (K + j Kh - w^2 M + j w C)^-1 (-M 1) a_g;
  an accelerometer reads -w^2 q + a_g (the base sensor a_g), an LVDT q;
* force at floor p: q = (K + j Kh - w^2 M + j w C)^-1 e_p; accelerometers -w^2 q, LVDTs q.

Then z = ln|H_estimate / H_true| / sigma at every point, with sigma from the case's own
noise model (``nlp.frf.noise.sigma_ln``). If the model is right, mean z^2 is 1 wherever it is
taken. Printed: mean and median z^2 on the fitted half-power windows, on the held-out
shoulders (windows 3x wider, minus the fitted ones) and over the whole band, and the median
ratio of the local error (RMS over 21 points) to sigma in the tenth of points where |H| is
smallest (anti-resonances), largest (peaks), and in between.

When the model carries the estimate's window (Welch records, FRF files with coherence:
``case.target.kernel``), the truth is also smoothed by the same three taps, which is what
the fit compares with, and the fitted points' mean z^2 against it is printed with its
sampling spread: a block bootstrap over frequencies (blocks of 4 bins, every channel of a
bin together, since the errors of one bin are shared by the channels through the input).
With ``--split`` a Welch case is also split into halves of its record, and the mean of
(ln|H_a / H_b|)^2 / (var_a + var_b) over the band is printed: the noise model checked on
the records alone. A summary over the cases closes the output.

For an FRF file (an average with a Hann window at the file's own resolution), the expected
estimate is also computed exactly, as the true FRF convolved with the window's power kernel
on a grid of 1/16 bin (+-8 bins), to check the resolution-bias term of the noise model at the
fitted points where that bias exceeds 0.05: the slope of the actual error on the exact bias,
the median ratio of the model's bias formula to the exact one, and (with coherence) mean and
median z^2 of the coherence variance alone, against the truth and against the smoothed truth.

    python research/noise_at_truth.py BENCH/62_null_frf [BENCH/51_null ...] [--split]
"""

import argparse
import json
import os
import sys

import numpy as np
from scipy.ndimage import uniform_filter1d

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from nlp.case.assemble import assemble  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.fitting import _windows  # noqa: E402
from nlp.diagnosis.spread import effective_points  # noqa: E402
from nlp.frf.kernel import kernel_moment, resolution_bias, welch_averages  # noqa: E402
from nlp.frf.noise import sigma_ln  # noqa: E402
from nlp.frf.variance import var_ln_welch  # noqa: E402


def true_frf(truth, case):
    """(n_ch, n_f) FRF of the true system at the case's channels and frequencies."""
    S = truth["system"]
    M, C, K = (np.asarray(S[k], float) for k in ("M", "C", "K"))
    Kh = np.asarray(S.get("Kh") or np.zeros_like(K), float)
    n = M.shape[0]
    ground = truth["excitation"] == "ground"
    b = -M @ np.ones(n) if ground else np.eye(n)[truth["force_floor"] - 1]
    out = []
    for w in 2 * np.pi * case.f:
        q = np.linalg.solve(K + 1j * Kh - w ** 2 * M + 1j * w * C, b)
        row = []
        for ch in case.config.data.channels:
            i = int(ch.floor)
            disp = (ch.quantity == "displacement") or (ch.output in ("receptance",))
            if i == 0:
                row.append(1.0 + 0j if (ground and not disp) else 0j)
            elif disp:
                row.append(q[i - 1])
            else:   # records are absolute accelerations; a file says which it holds
                absolute = ground and ch.output != "accelerance"
                row.append(-w ** 2 * q[i - 1] + (1.0 if absolute else 0.0))
        out.append(row)
    return np.array(out).T


class _At:
    """The frequencies and channels true_frf needs, at shifted frequencies."""

    def __init__(self, case, f):
        self.f, self.config = f, case.config


def smoothed_frf(truth, case, per_bin=16, half=8):
    """Expected Hann-windowed average of the true FRF: its convolution with the window's
    power kernel |W(nu)|^2, nu in bins (a flat input spectrum)."""
    L = 4096
    w = np.hanning(L + 1)[:-1]                       # periodic Hann
    K = np.abs(np.fft.fft(w, L * per_bin)) ** 2
    nu = np.fft.fftfreq(L * per_bin, d=1.0 / L)
    keep = np.abs(nu) <= half
    nu, K = nu[keep], K[keep] / K[keep].sum()
    df = case.f[1] - case.f[0]
    return sum(k * true_frf(truth, _At(case, case.f + v * df)) for v, k in zip(nu, K))


def bias_lines(truth, case, cfg, Ht, keep, fit):
    """The resolution-bias check of an FRF file (see the module docstring)."""
    if truth["route"] != "frf_file" or cfg.data.window != "hann":
        return []
    Hs = smoothed_frf(truth, case)
    e = np.log(np.abs(case.H / Ht))[keep][:, fit]
    b = np.log(np.abs(Hs / Ht))[keep][:, fit]
    formula = resolution_bias(Ht, kernel_moment("hann", 1024))[keep][:, fit]
    big = np.abs(b) > 0.05
    if not big.any():
        return ["  resolution bias: no fitted point with an exact bias over 0.05"]
    lines = [f"  resolution bias at {int(big.sum())} fitted points with |b| > 0.05: slope of the "
             f"error on the exact bias {np.sum(e[big] * b[big]) / np.sum(b[big] ** 2):.2f}, "
             f"formula / exact (median) {np.median(formula[big] / b[big]):.2f}"]
    if case.coherence is not None and case.n_averages:
        var = var_ln_welch(case.coherence, float(case.n_averages))[keep][:, fit]
        for name, err in (("truth", e), ("smoothed truth", e - b)):
            z2 = err ** 2 / var
            lines.append(f"  coherence variance alone against the {name}: mean z^2 "
                         f"{np.mean(z2):.2f}, median {np.median(z2):.2f}")
    return lines


def kernel_lines(truth, case, keep, fit, stats):
    """Fitted points against the truth smoothed by the model's own three taps."""
    h, a = case.target.kernel                     # h in rad/s
    dh = h / (2 * np.pi)
    Hk = (a * true_frf(truth, _At(case, case.f - dh)) + (1 - 2 * a) * true_frf(truth, case)
          + a * true_frf(truth, _At(case, case.f + dh)))
    z = np.log(np.abs(case.H[keep][:, fit] / Hk[keep][:, fit])) / sigma_ln(case, fit)[keep]
    z2 = z ** 2
    col = z2.mean(axis=0)
    nb = max(col.size // 4, 1)
    blocks = col[:nb * 4].reshape(nb, -1).mean(axis=1) if col.size >= 4 else col
    rng = np.random.default_rng(0)
    boot = [blocks[rng.integers(0, blocks.size, blocks.size)].mean() for _ in range(2000)]
    stats["truth"].append(float(z2.mean()))
    n_eff = effective_points(z, fit)
    stats.setdefault("implied", []).append(float(np.sqrt(2.0 / n_eff)))
    return [f"  fitted points against the truth seen through the model's window (three taps): "
            f"mean z^2 {z2.mean():.2f} +- {np.std(boot):.2f} (block bootstrap, "
            f"{col.size} frequencies), median z^2 {np.median(z2):.2f}",
            f"  errors correlated between channels and neighbouring bins: {n_eff:.0f} effective "
            f"independent points of {z2.size}; a right noise model would give this mean z^2 "
            f"within +- {np.sqrt(2.0 / n_eff):.2f} (1 SD, Gaussian errors)"]


def split_lines(case, cfg, keep, stats):
    """The noise model on the records alone: the two halves of the record against each other."""
    from scipy import signal
    rec = case.records
    L = int(cfg.data.nperseg)
    x = rec.data["__input__"]
    y = np.array([rec.data[c.name] for c in case.channels])
    n = x.size // 2
    halves = []
    for sl in (slice(0, n), slice(n, 2 * n)):
        kw = dict(fs=rec.fs, window=cfg.data.window, nperseg=L, noverlap=int(cfg.data.overlap * L))
        f, sxx = signal.welch(x[sl], **kw)
        _, syy = signal.welch(y[:, sl], axis=-1, **kw)
        _, sxy = signal.csd(x[sl][None], y[:, sl], axis=-1, **kw)
        i = np.searchsorted(f, case.f - 1e-9 * (f[1] - f[0]))
        g2 = (np.abs(sxy) ** 2 / (sxx * syy))[:, i]
        n_eff = welch_averages(n, L, int(cfg.data.overlap * L), cfg.data.window)[1]
        halves.append(((sxy / sxx)[:, i], var_ln_welch(g2, n_eff)))
    (Ha, va), (Hb, vb) = halves
    band = np.where((case.f >= cfg.frequencies.fmin) & (case.f <= cfg.frequencies.fmax))[0]
    band = band[np.all(case.coherence[:, band] > cfg.frequencies.min_coherence, axis=0)]
    q = (np.log(np.abs(Ha / Hb)) ** 2 / (va + vb))[keep][:, band]
    stats["split"].append(float(q.mean()))
    return [f"  halves of the record against each other over the band: mean "
            f"(ln|Ha/Hb|)^2 / (var_a + var_b) {q.mean():.2f} ({q.size} points)"]


def report(folder, split=False, stats=None):
    truth = json.load(open(os.path.join(folder, "truth.json")))
    if truth.get("effects"):
        return f"{folder}: has effects, skipped (the truth system then differs from the case's model)"
    cfg = load_case(os.path.join(folder, "case.yaml"))
    case = assemble(cfg)
    Ht = true_frf(truth, case)
    # a base accelerometer under a force input reads 0 at every frequency (an accelerance
    # is also 0 at 0 Hz, so "all" would drop every accelerometer of a force input)
    keep = np.any(np.abs(Ht) > 0, axis=1)
    band = np.where((case.f >= cfg.frequencies.fmin) & (case.f <= cfg.frequencies.fmax))[0]
    fit = _windows(cfg, case, 1)
    held = np.setdiff1d(_windows(cfg, case, 3), fit)
    lines = [f"{folder}: route {truth['route']}, {truth['excitation']} input"]
    for name, idx in (("fitted", fit), ("held-out", held), ("band", band)):
        z = np.log(np.abs(case.H[keep][:, idx] / Ht[keep][:, idx])) / sigma_ln(case, idx)[keep]
        lines.append(f"  {name:9s} {z.size:6d} points: mean z^2 {np.mean(z ** 2):5.2f}, "
                     f"median z^2 {np.median(z ** 2):5.2f} (0.45 for Gaussian errors)")
    e = np.log(np.abs(case.H[keep][:, band] / Ht[keep][:, band]))
    ratio = np.sqrt(uniform_filter1d(e ** 2, 21, axis=1)) / sigma_ln(case, band)[keep]
    depth = np.log(np.abs(Ht[keep][:, band]))
    lo = depth < np.percentile(depth, 10, axis=1, keepdims=True)
    hi = depth > np.percentile(depth, 90, axis=1, keepdims=True)
    lines.append(f"  local error / sigma, median: anti-resonance tenth {np.median(ratio[lo]):.2f}, "
                 f"peak tenth {np.median(ratio[hi]):.2f}, between {np.median(ratio[~lo & ~hi]):.2f}")
    lines += bias_lines(truth, case, cfg, Ht, keep, fit)
    stats = stats if stats is not None else {"truth": [], "split": []}
    if case.target.kernel:
        lines += kernel_lines(truth, case, keep, fit, stats)
        if split and case.records is not None and "__input__" in case.records.data:
            lines += split_lines(case, cfg, keep, stats)
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="+", help="blind benchmark case folders (null or ordinary)")
    ap.add_argument("--split", action="store_true",
                    help="also check a Welch case's noise model on the two halves of its record")
    a = ap.parse_args()
    stats = {"truth": [], "split": []}
    for folder in a.cases:
        print(report(folder, a.split, stats), flush=True)
    v = np.array(stats["truth"])
    if v.size > 1:
        print(f"{v.size} cases, fitted points against the truth through the window: mean z^2 "
              f"{v.mean():.3f}, SD {v.std(ddof=1):.3f}, range {v.min():.2f}-{v.max():.2f}, "
              f"{int(np.sum((v < 0.8) | (v > 1.3)))} outside 0.8-1.3; the SD that sampling alone "
              f"gives a right model, median over the cases: {np.median(stats['implied']):.3f}")
    w = np.array(stats["split"])
    if w.size > 1 and w.size == v.size:
        print(f"  halves of the records: mean {w.mean():.3f}; correlation with the above "
              f"{np.corrcoef(v, w)[0, 1]:+.2f}")


if __name__ == "__main__":
    main()
