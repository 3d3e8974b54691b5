"""Closed-form variance of ln|H| of an FRF estimate, per route: one segment of a
transient (errors in variables, with the noise measured in the record's rest portions)
and Welch averages (from the coherence); Bendat & Piersol."""

import math

import numpy as np
from scipy import signal
from scipy.special import exp1

from nlp.io.quality import true_runs

__all__ = ["VAR_LN_MAX", "SIGMA_FLOOR", "var_ln_welch", "var_ln_transient", "rest_mask",
           "rest_noise_psd"]

# ln|z| of a complex Gaussian z has variance pi^2/24 (pure noise: no signal left)
VAR_LN_MAX = math.pi ** 2 / 24
SIGMA_FLOOR = 1e-4      # sigma floor (numerical resolution of a stored FRF)


def var_ln_welch(coherence, n_eff):
    """Var ln|H1| = (1 - g^2) / (2 n g^2), capped at the pure-noise value."""
    g2 = np.clip(np.asarray(coherence, float), 1e-12, 1.0)
    return np.minimum((1 - g2) / (2 * n_eff * g2), VAR_LN_MAX)


def var_ln_transient(p_xx, p_yy, s_nx, s_ny):
    """Var ln|Y/X| for one segment (errors in variables), bias included.

    First order: (S_ny/|HU|^2 + S_nx/|U|^2) / 2. Where the signal-to-noise
    ratio is low, ln|.| of a noisy spectrum is biased: for complex-circular
    noise of relative power s, E ln|1 + e| = E1(1/s) / 2 (E1 the exponential
    integral), so ln|H| is biased by (E1(1/s_y) - E1(1/s_x)) / 2; both terms are
    added in quadrature, so noise-dominated points do not pass as data.

    Parameters
    ----------
    p_xx : ndarray, shape (n_f,)
        Periodogram of the input record (density scaling, unit^2/Hz).
    p_yy : ndarray, shape (n_ch, n_f)
        Periodograms of the outputs, same window and scaling.
    s_nx, s_ny : ndarray, shapes (n_f,) and (n_ch, n_f)
        Noise spectral densities of input and outputs (same scaling).
    """
    def rel(noise, total):  # noise power over signal power, signal = total - noise
        with np.errstate(divide="ignore", invalid="ignore"):
            r = noise / np.maximum(total - noise, 1e-3 * noise)
        return np.clip(np.nan_to_num(r, nan=1e3, posinf=1e3), 0.0, 1e3)

    s_y, s_x = rel(s_ny, p_yy), rel(s_nx, p_xx)[None, :]
    with np.errstate(divide="ignore", over="ignore"):
        b_y, b_x = (0.5 * exp1(1 / np.maximum(v, 1e-12)) for v in (s_y, s_x))
    # in quadrature, not as the difference: where both records are noise they
    # do not cancel, the point carries no information
    return np.minimum(0.5 * (s_y + s_x), VAR_LN_MAX) + b_y ** 2 + b_x ** 2


# --------------------------------------------------------------- rest portions
def _block_rms(v, L):
    nb = v.size // L
    return np.sqrt(np.mean(v[:nb * L].reshape(nb, L) ** 2, axis=1))


def rest_mask(x, y, fs, block_s=None, contrast=8.0, margin=1.5):
    """Samples where the input and every output are at rest (noise only).

    The record is cut into blocks; a block is at rest when the RMS of the input
    and of each output is within ``margin`` of that record's quietest block.
    The input decides whether the record has a rest portion at all: its median
    block must be at least ``contrast`` times louder than the quietest one
    (else the quietest block is signal, not noise, and None is returned).

    Parameters
    ----------
    x : ndarray (N,), y : ndarray (n_ch, N)
        Input and outputs (mean removed or not).
    fs : float
        Sampling frequency [Hz].

    Returns
    -------
    ndarray of bool, shape (N,), or None
    """
    n = x.size
    L = max(int(block_s * fs) if block_s else n // 100, 16)
    if n < 8 * L:
        return None
    keep = None
    for k, v in enumerate((x, *np.atleast_2d(y))):
        rms = _block_rms(v - np.mean(v), L)
        lo = rms.min()
        if not lo > 0 or (k == 0 and np.median(rms) < contrast * lo):
            return None
        quiet = rms <= margin * lo
        keep = quiet if keep is None else keep & quiet
    if keep.sum() < 4:
        return None
    mask = np.zeros(n, bool)
    mask[:keep.size * L] = np.repeat(keep, L)
    return mask


def rest_noise_psd(v, fs, mask, f, max_nperseg=128):
    """Noise spectral density (one-sided, unit^2/Hz) of records in their rest portions.

    Welch averages over every contiguous rest run (each at least one segment)
    with short segments, smoothed over 5 frequency bins, interpolated onto f:
    an estimate of the noise level that scatters from one bin to the next would
    inflate the chi-square (E[1/s^2] > 1/E[s]^2). v : (n_ch, N) records.

    Returns
    -------
    ndarray, shape (n_ch, f.size), or None when the rest runs are too short.
    """
    v = np.atleast_2d(v)
    runs = [(a, b) for a, b in true_runs(mask)]
    longest = max((b - a for a, b in runs), default=0)
    nper = int(2 ** math.floor(math.log2(max(min(longest, max_nperseg), 1))))
    if nper < 16:
        return None
    acc, count = 0.0, 0
    for a, b in runs:
        if b - a < nper:
            continue
        fw, p = signal.welch(v[:, a:b], fs=fs, nperseg=nper, axis=-1)
        k = (b - a - nper) // (nper // 2) + 1
        acc, count = acc + k * p, count + k
    p = acc / count
    # the segments' mean removal takes bin 0 and, through the Hann window's main lobe,
    # part of bin 1; smoothed over 5 bins that read 20-45 % low below 2.5 bins (measured
    # on white noise at fs 100 Hz: 0.76-0.86 of the mid-band level at 1.6 Hz, where a
    # blind case's first mode sat with a chi-square of 2; docs/benchmarks/history.md);
    # hold bin 2's level below it
    p[:, :2] = p[:, 2:3]
    kern = np.ones(5) / 5
    p = np.array([np.convolve(np.pad(pc, 2, mode="edge"), kern, mode="valid") for pc in p])
    return np.array([np.interp(f, fw, pc) for pc in p])
