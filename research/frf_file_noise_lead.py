"""A lead, not in the package: the noise of an FRF file without coherence from a local
rational fit, against the scatter of third differences that the package uses.

    python research/frf_file_noise_lead.py CASEDIR [CASEDIR ...]   # blind FRF files
    python research/frf_file_noise_lead.py --sim                    # scipy single-mode files
    python research/frf_file_noise_lead.py --known                  # independent errors
    python research/frf_file_noise_lead.py --coherence CASEDIR ...  # leakage in stored coherence

For each blind null FRF file (truth.json beside case.yaml) it compares ln|H| with the
truth seen through the Hann power kernel (research/noise_at_truth.py) at the fitted
points, over two sigmas: the package's (nlp.frf.noise.noise_model) and the local rational
one below plus LEAKAGE share 0.1 of the squared resolution bias. It prints each file's
mean z^2, then the pooled median and tails, which for a right sigma are those of
chi-square(1): median 0.455, 4.55 % above 4, 0.27 % above 9.

``--known`` puts independent errors of known variance on an exact FRF (the one case
where counting the bins as independent is right) and prints the estimate over the truth.
``--sim`` runs the same local rational sigma on the single-mode Welch files of
tests/test_noise.py (scipy filter, 20 records) and prints z^2 at the 7 peak bins and in
the shoulders, and the lag-1 to lag-3 correlation of the errors in the shoulders.

The local rational fit: at bin k, over the 2R + 1 bins around it, N_c(x) / D(x) with a
quadratic N_c per channel and D = 1 + d1 x + d2 x^2 common to the channels (one pole
pair), linearised as H_c D = N_c; Var ln|H| = sum |residual / H|^2 / (2 dof), the bins
counted as independent (the local rational method of McKelvey and Guerin, 2012, without
the input spectrum, which a file does not hold).
"""

import json
import math
import os
import sys
import warnings

import numpy as np
from scipy.ndimage import uniform_filter1d

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)

from nlp.frf import noise as N  # noqa: E402

LEAKAGE = 0.1
HALF_WIDTH = 4


def local_rational_var(H, R=HALF_WIDTH):
    """(n_ch, n_f) Var ln|H| from a local rational fit over 2R + 1 bins (see above)."""
    H = np.atleast_2d(np.asarray(H, complex))
    C, n = H.shape
    W = 2 * R + 1
    x = np.arange(-R, R + 1, dtype=float)
    npar = 3 * C + 2
    dof = (C * W - npar) / C
    A = np.zeros((C * W, npar), complex)
    for c in range(C):
        for j in range(3):
            A[c * W:(c + 1) * W, 3 * c + j] = x ** j
    var = np.empty((C, n))
    for k in range(R, n - R):
        h = H[:, k - R:k + R + 1]
        for c in range(C):
            A[c * W:(c + 1) * W, 3 * C] = -x * h[c]
            A[c * W:(c + 1) * W, 3 * C + 1] = -x ** 2 * h[c]
        sc = np.linalg.norm(A, axis=0)
        sc[sc == 0] = 1.0
        th = np.linalg.lstsq(A / sc, h.ravel(), rcond=None)[0] / sc
        D = 1.0 + th[3 * C] * x + th[3 * C + 1] * x ** 2
        r = (h.ravel() - A @ th).reshape(C, W) / D        # h - N / D
        var[:, k] = np.sum(np.abs(r / h) ** 2, axis=1) / (2.0 * dof)
    var[:, :R] = var[:, R:R + 1]
    var[:, n - R:] = var[:, n - R - 1:n - R]
    return var


def lead_var(f, H, window="hann"):
    """The local rational variance plus LEAKAGE x the squared resolution bias (as the
    package reads it: less the noise's own share, spread over +-1 bin)."""
    v = local_rational_var(H)
    b2 = N._file_resolution_bias2(f, H, window)
    if np.ndim(b2):
        m2 = N.kernel_moment(window, 1024)
        b2 = np.clip(b2 - (0.5 * m2) ** 2 * N.second_difference_factor(window) * v, 0, None)
        b2 = uniform_filter1d(b2, 3, axis=-1, mode="nearest")
    return v + LEAKAGE * b2


def blind(folders):
    from noise_at_truth import smoothed_frf
    from nlp.case.assemble import assemble
    from nlp.case.load import load_case
    from nlp.diagnosis.fitting import _windows
    pooled = {"package": [], "local rational": []}
    means = {"package": [], "local rational": []}
    for folder in folders:
        with open(os.path.join(folder, "truth.json")) as fh:
            truth = json.load(fh)
        cfg = load_case(os.path.join(folder, "case.yaml"))
        case = assemble(cfg)
        Hs = smoothed_frf(truth, case)
        keep = np.all(np.abs(Hs) > 0, axis=1)
        fit = _windows(cfg, case, 1)
        e2 = np.log(np.abs(case.H / Hs)) ** 2
        sig2 = {"package": N.sigma_ln(case, np.arange(case.f.size)) ** 2,
                "local rational": lead_var(case.f, case.H, cfg.data.window)}
        row = []
        for k, v in sig2.items():
            z2 = (e2 / v)[keep][:, fit].ravel()
            pooled[k].append(z2)
            means[k].append(z2.mean())
            row.append(f"{k} {z2.mean():.2f}")
        print(f"{folder}: mean z^2 at the fitted points: " + ", ".join(row), flush=True)
    for k in pooled:
        z = np.concatenate(pooled[k])
        m = np.array(means[k])
        print(f"{k:15s} per file mean {m.mean():.2f} SD {m.std():.2f} range {m.min():.2f}-"
              f"{m.max():.2f} ({int(np.sum((m < 0.8) | (m > 1.3)))} of {m.size} outside "
              f"0.8-1.3); pooled {z.size} points: median {np.median(z):.3f}, above 4 "
              f"{100 * np.mean(z > 4):.2f} %, above 9 {100 * np.mean(z > 9):.2f} %")


def sim():
    from scipy import signal
    sys.path.insert(0, os.path.join(HERE, "..", "tests", "frf"))
    from test_noise import _welch_file_of_a_sharp_mode
    fs, fn = 50.0, 5.0
    for zeta in (0.01, 0.02):
        wn = 2 * math.pi * fn
        b, a = signal.bilinear([wn ** 2], [1, 2 * zeta * wn, wn ** 2], fs)
        zp, zs, cs = [], [], []
        for seed in range(20):
            f, H, Ht = _welch_file_of_a_sharp_mode(seed, zeta)
            h, w = N.smoothing_taps("hann", 2048)
            df = f[1] - f[0]
            Hs = sum(g * signal.freqz(b, a, worN=f + s * h * df, fs=fs)[1]
                     for g, s in ((w, -1), (1 - 2 * w, 0), (w, 1)))
            e = np.log(H / Hs)
            v = local_rational_var(H[None])[0]
            k = int(np.argmax(np.abs(Ht)))
            sh = (f > 1) & (f < 3)
            zp.append(np.mean((e.real ** 2 / v)[k - 3:k + 4]))
            zs.append(np.mean((e.real ** 2 / v)[sh]))
            r = e.real[sh] - e.real[sh].mean()
            cs.append([np.sum(r[:-lag] * r[lag:]) / np.sum(r * r) for lag in (1, 2, 3)])
        print(f"zeta {zeta}: local rational alone, mean z^2 at the 7 peak bins "
              f"{np.mean(zp):.2f}, in the shoulders (1-3 Hz) {np.mean(zs):.2f}; error "
              f"correlation in the shoulders at lags 1-3: {np.round(np.mean(cs, axis=0), 2)}")


def coherence(folders, per_bin=16, half=8):
    """Files with coherence: the window's coherence loss predicted from the true FRF,
    (<|H|^2> - |<H>|^2) / |<H>|^2 over the Hann power kernel, against the stored
    (1 - g^2) / g^2, at the fitted points where the prediction exceeds 0.02 (leakage
    dominates)."""
    from noise_at_truth import true_frf, _At
    from nlp.case.assemble import assemble
    from nlp.case.load import load_case
    from nlp.diagnosis.fitting import _windows
    L = 4096
    w = np.hanning(L + 1)[:-1]
    K = np.abs(np.fft.fft(w, L * per_bin)) ** 2
    nu = np.fft.fftfreq(L * per_bin, d=1.0 / L)
    keep = np.abs(nu) <= half
    nu, K = nu[keep], K[keep] / K[keep].sum()
    for folder in folders:
        with open(os.path.join(folder, "truth.json")) as fh:
            truth = json.load(fh)
        cfg = load_case(os.path.join(folder, "case.yaml"))
        case = assemble(cfg)
        fit = _windows(cfg, case, 1)
        df = case.f[1] - case.f[0]
        H1 = H2 = 0.0
        for v, k in zip(nu, K):
            h = true_frf(truth, _At(case, case.f + v * df))
            H1, H2 = H1 + k * h, H2 + k * np.abs(h) ** 2
        pred = (H2 - np.abs(H1) ** 2) / np.abs(H1) ** 2
        obs = (1 - case.coherence) / case.coherence
        pred, obs = pred[:, fit], obs[:, fit]
        big = pred > 0.02
        print(f"{folder}: predicted / stored (1 - g^2) / g^2 at {int(big.sum())} fitted points: median "
              f"{np.median(pred[big] / obs[big]):.2f}")


def known():
    """Independent complex Gaussian relative errors of known variance on an exact
    two-mode FRF (3 channels) and on a flat one: the estimate over the truth."""
    rng = np.random.default_rng(5)
    f = np.linspace(1.0, 20.0, 800)
    modes = [(5.0, 0.02), (12.0, 0.015)]
    H = np.array([sum(r / (fn ** 2 - f ** 2 + 2j * z * fn * f) for (fn, z) in modes)
                  for r in (1.0, -0.7, 0.4)])
    s2 = 0.01 ** 2 / 2                                  # Var ln|H| of the errors
    for name, H0 in (("two modes", H), ("flat", np.ones_like(H))):
        for C in (1, 3):
            v = []
            for _ in range(10):
                e = 0.01 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape))
                v.append(local_rational_var((H0 * (1 + e / np.sqrt(2)))[:C]))
            v = np.mean(v, axis=0)[:, 10:-10] / s2
            print(f"{name}, {C} channel(s): estimate / true variance, mean {v.mean():.2f}, "
                  f"median {np.median(v):.2f}")


if __name__ == "__main__":
    warnings.filterwarnings("ignore")
    if sys.argv[1:] == ["--sim"]:
        sim()
    elif sys.argv[1:] == ["--known"]:
        known()
    elif sys.argv[1:2] == ["--coherence"]:
        coherence(sys.argv[2:])
    elif sys.argv[1:]:
        blind(sys.argv[1:])
    else:
        print(__doc__.split("\n\n")[1])
        sys.exit(2)
