"""The noise of an FRF read from its own scatter along frequency: robust levels of
second (or spaced third) differences of ln H, corrected for the correlation that a
window gives neighbouring bins."""

import math

import numpy as np
from scipy.signal import get_window

from nlp.frf.variance import SIGMA_FLOOR

__all__ = ["second_difference_factor", "local_scatter", "robust_levels", "correlation_lag",
           "spaced_scatter"]


def second_difference_factor(window=None):
    """Variance of a second difference of the errors of a windowed spectral estimate,
    in units of the point variance: 6 - 8 rho_1 + 2 rho_2.

    The DFT of a window w makes the noise of neighbouring bins correlated, with
    complex correlation c_l = sum w^2 exp(-2 pi i l n / N) / sum w^2; an FRF
    estimate (a ratio of cross- to auto-spectra) inherits rho_l = |c_l|^2. Boxcar
    (one whole record) or ``None``/``"none"``: independent bins, factor 6. Hann:
    c_1 = -2/3, c_2 = 1/6, factor 2.5, so a scatter that assumed 6 would make the
    noise 1.55 x too small.
    """
    if window is None or window in ("none", "boxcar"):
        return 6.0
    N = 4096
    w2 = get_window(window, N) ** 2
    n = np.arange(N)
    rho = [abs(np.sum(w2 * np.exp(-2j * np.pi * lag * n / N)) / np.sum(w2)) ** 2
           for lag in (1, 2)]
    return 6.0 - 8.0 * rho[0] + 2.0 * rho[1]


def local_scatter(f, H, half_width=25, window=None):
    """Std of ln|H| and arg H from the robust scatter of second differences along frequency.

    For errors of variance s^2 at each point, the second difference has
    variance :func:`second_difference_factor` x s^2 (6 for independent points;
    less for a windowed estimate, whose neighbouring bins are correlated); the
    median absolute deviation in a sliding window of 2 half_width + 1 points
    (x 1.4826) is robust to the curvature of the smooth FRF at its peaks.

    window : the estimate's analysis window (scipy name), or None for
        independent points.

    Returns
    -------
    sigma_ln, sigma_phase : ndarrays, shape (n_ch, n_f)
    """
    H = np.atleast_2d(np.asarray(H, complex))
    lnH = _ln_unwrapped(H)
    d2 = lnH[:, 2:] - 2 * lnH[:, 1:-1] + lnH[:, :-2]
    return robust_levels(d2, H.shape[1], 1, half_width, second_difference_factor(window))


def _ln_unwrapped(H):
    """ln H with the phase unwrapped along frequency (zeros read as 1e-300)."""
    with np.errstate(divide="ignore"):
        lnH = np.log(np.where(H == 0, 1e-300, H))
    return lnH.real + 1j * np.unwrap(lnH.imag, axis=1)


def robust_levels(d, n, shift, half_width, factor):
    """Point std behind differences d (n_ch, n - 2 shift) of variance factor x s^2:
    1.4826 x the median absolute deviation over 2 half_width + 1 differences around
    each of the n points, for the real and the imaginary part."""
    root = math.sqrt(factor)
    out = []
    for part in (d.real, d.imag):
        s = np.empty((d.shape[0], n))
        for k in range(n):
            j = min(max(k - shift, 0), part.shape[1] - 1)   # the difference centred on k
            seg = part[:, max(j - half_width, 0):j + half_width + 1]
            med = np.median(seg, axis=1, keepdims=True)
            s[:, k] = 1.4826 * np.median(np.abs(seg - med), axis=1) / root
        out.append(np.maximum(s, SIGMA_FLOOR))
    return out[0], out[1]


def correlation_lag(window=None, tol=1e-3):
    """Smallest bin lag beyond which a ``window``'s spectral estimate has uncorrelated
    bins: 1 + the largest l with |c_l| > tol (c_l as in :func:`second_difference_factor`).
    1 for independent bins (None, ``"none"``, ``"boxcar"``); 3 for Hann and Hamming
    (w^2 holds cosines up to 2 x the fundamental)."""
    if window is None or window in ("none", "boxcar"):
        return 1
    N = 4096
    w2 = get_window(window, N) ** 2
    c = np.abs(np.fft.fft(w2)) / np.sum(w2)
    big = np.flatnonzero(c[1:N // 2] > tol)
    return int(big.max()) + 2 if big.size else 1


def spaced_scatter(f, H, half_width=25, window=None):
    """Std of ln|H| and arg H from third differences of bins ``lag`` apart
    (:func:`correlation_lag` of the window: 3 for Hann).

    The four terms of a third difference at that spacing are uncorrelated whatever
    the correlation of neighbouring bins, so it has variance 20 s^2 for noise and for
    leakage alike, and it removes the quadratic part of a peak. Near the peaks of a
    windowed average the error is mostly leakage of the response that outlasts a
    segment: a smooth term times one windowed spectrum, whose neighbouring bins
    correlate like the window's DFT itself (c_1 = -2/3 for Hann) rather than like
    noise (|c_1|^2 = 4/9). Adjacent second differences read that 2.2 x too large, and
    the robust level over 51 bins carries it into the shoulders, where the fit lives.
    Measured against the true FRF on 11 blind null FRF files without coherence (Hann,
    4096-point segments, 1-2.7 bins per half-power bandwidth; 3 retired held-back
    seeds, 8 development seeds), mean z^2 on the fitted windows, with the resolution
    bias added as in :func:`nlp.frf.noise.noise_model`, was 0.55-1.14 with :func:`local_scatter`
    and 0.83-1.30 with this. The leakage scatter of the peak bins themselves is not
    seen by either (a level over 51 bins).

    Returns
    -------
    sigma_ln, sigma_phase : ndarrays, shape (n_ch, n_f)
    """
    H = np.atleast_2d(np.asarray(H, complex))
    lnH = _ln_unwrapped(H)
    lag = correlation_lag(window)
    g = np.array([-1.0, 3.0, -3.0, 1.0])
    span = 3 * lag
    n = H.shape[1]
    if n <= span + 2:
        return local_scatter(f, H, half_width, window)
    d3 = sum(g[j] * lnH[:, j * lag:n - span + j * lag] for j in range(4))
    return robust_levels(d3, n, span // 2, half_width, float(np.sum(g ** 2)))
