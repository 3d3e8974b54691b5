"""Frequency-point selection around resonances (paper Section 4.2).

Points far from resonance have a low signal-to-noise ratio and carry little
damping information, so the updating uses the peak areas only: the
half-power band of each resonance, widened by a factor ``k``.
"""

import math
import os

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np
from scipy import signal

from nlp.errors import InputError
from nlp.frf.scatter import local_scatter

__all__ = ["match_modes", "unresolved_points", "band_mask", "find_peaks", "half_power_band", "select_frequencies", "plot_selection",
           "peak_curve"]

_SRC = "<arguments>"


def _check_fh(f, H):
    """f as a strictly increasing 1-D array, H as (n_ch, n_f)."""
    f = np.asarray(f, dtype=float)
    H = np.atleast_2d(np.asarray(H))
    if f.ndim != 1 or f.size < 3 or np.any(np.diff(f) <= 0):
        raise InputError(_SRC, "f", "a strictly increasing 1-D frequency grid of >= 3 points [Hz]")
    if H.ndim != 2 or H.shape[1] != f.size:
        raise InputError(_SRC, "H", f"FRFs shaped (n_channels, {f.size})", got=f"shape {H.shape}")
    return f, H


def band_mask(f, fmin, fmax):
    """Boolean mask of fmin <= f <= fmax [Hz] (open ends when None)."""
    lo = -np.inf if fmin is None else fmin
    hi = np.inf if fmax is None else fmax
    if lo >= hi:
        raise InputError(_SRC, "fmin", f"below fmax ({fmax} Hz)", got=fmin)
    return (f >= lo) & (f <= hi)


def _summed_mag(H):
    """Sum over channels of |H|: every mode shows up in it (paper's overlay)."""
    return np.sum(np.abs(H), axis=0)


def find_peaks(f, H, n_peaks=None, prominence_db=6.0, fmin=None, fmax=None, min_level=None,
               sigma=None, z_noise=5.0):
    """Resonance peaks of the FRF magnitudes (each channel and their sum).

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies [Hz], increasing.
    H : array_like, shape (n_ch, n_f) or (n_f,)
        FRFs.
    n_peaks : int, optional
        Keep only the ``n_peaks`` most prominent peaks.
    prominence_db : float
        Minimum peak prominence of ``20 log10(sum_ch |H|)`` [dB].
    fmin, fmax : float, optional
        Search only in ``[fmin, fmax]`` [Hz].
    min_level : float, optional
        Ignore peaks of a channel whose magnitude is below this (e.g. 1 for
        absolute-acceleration transmissibility, where resonances amplify and
        noise-made bumps above the last mode do not).
    sigma : array_like, shape (n_ch, n_f), optional
        Standard deviation of ln|H| (:mod:`nlp.frf.noise`); default: the robust
        local scatter of each curve along frequency.
    z_noise : float
        A peak must stand out of the noise: its height in ln|H| above the
        median of the curve within +-5 % of its frequency must exceed
        ``z_noise`` standard deviations of the noise at the peak.

    Returns
    -------
    ndarray of int
        Indices into ``f`` of the peaks, sorted by frequency.

    Notes
    -----
    A peak is kept when a strict majority of the channels, or the channel
    sum, peak there: a bump between two anti-resonances of one channel is not
    a resonance. For complex ``H`` a peak of fewer channels is kept too when
    the phase of a channel peaking there lags by at least 45 deg across the
    peak's half-power band: a pole lags by 90 deg over that band, whereas
    between two zeros the phase does not fall, so a mode near the nodes of
    the other channels is not lost. Real ``H`` (magnitudes only) uses the
    majority rule alone.
    """
    f, H = _check_fh(f, H)
    if n_peaks is not None and (int(n_peaks) != n_peaks or n_peaks < 1):
        raise InputError(_SRC, "n_peaks", "a positive integer", got=n_peaks)
    sel = np.flatnonzero(band_mask(f, fmin, fmax))
    # Peaks of every channel and of the channel sum: a mode that one channel
    # barely shows (or that the 1/w^2 fall of a receptance hides in the sum)
    # is still found in another.
    # A resonance shows in most channels; a bump between two anti-resonances
    # of one channel does not, so candidates need the support of most
    # channels (or a peak of the channel sum).
    mags = np.abs(np.atleast_2d(H))[:, sel]
    curves = np.vstack([mags, mags.sum(axis=0)[None]])
    noise = _curve_noise(f[sel], mags, curves, sigma, sel)
    cands = _candidates(f[sel], curves, noise, prominence_db, min_level, z_noise)
    if not cands:
        return np.zeros(0, dtype=int)
    clusters = _clusters(cands, f[sel])
    idx, prom = _resonances(clusters, np.atleast_2d(H)[:, sel], mags)
    if n_peaks is not None and idx.size > n_peaks:
        idx = idx[np.argsort(prom)[::-1][: int(n_peaks)]]
    return np.unique(sel[idx])


def _curve_noise(f, mags, curves, sigma, sel):
    """Std of ln|.| of each curve (channels, then their sum) on the band's points ``sel``:
    the given sigma (the sum's is the magnitude-weighted channel noise), else the robust
    local scatter along frequency."""
    if sigma is None:
        return local_scatter(f, curves)[0]
    s_ch = np.atleast_2d(np.asarray(sigma, float))[:, sel]
    with np.errstate(invalid="ignore", divide="ignore"):
        s_sum = np.sqrt(np.sum((mags * s_ch) ** 2, axis=0)) / curves[-1]
    return np.vstack([s_ch, np.nan_to_num(s_sum, nan=np.inf)[None]])


def _candidates(f, curves, noise, prominence_db, min_level, z_noise):
    """(index, prominence [dB], curve number, significance) of every peak of every curve
    that is prominent enough and stands ``z_noise`` noise deviations out of its neighbours."""
    n_curves = curves.shape[0]
    cands = []
    for c, mag in enumerate(curves):
        with np.errstate(divide="ignore"):
            db = 20.0 * np.log10(mag)
        finite = np.isfinite(db)
        if not finite.any():
            continue
        db[~finite] = db[finite].min() - 100.0  # zero magnitude: a deep notch, not a gap
        idx, props = signal.find_peaks(db, prominence=prominence_db)
        prom = props["prominences"]
        if min_level is not None:
            keep = mag[idx] >= min_level * (n_curves - 1 if c == n_curves - 1 else 1)
            idx, prom = idx[keep], prom[keep]
        # height above the local median level (+-5 %), in noise standard deviations:
        # the prominence would measure a noise bump from the deep notches beside
        # it (ln|signal + noise| has a long lower tail), the median does not
        signif = np.array([(db[i] - np.median(db[max(i - h, 0):i + h + 1])) * math.log(10) / 20
                           for i, h in zip(idx, _half_widths(f, idx))]) / noise[c, idx]
        keep = signif >= z_noise
        cands += [(i, p, c, z) for i, p, z in zip(idx[keep], prom[keep], signif[keep])]
    return cands


def _clusters(cands, f):
    """[centre index, members (index, prominence, curve)]: candidates within 2 bins or 2 %
    of a more significant one join it."""
    # Group around the most significant candidates, never by chaining neighbours:
    # a chain of noise bumps would make one group spanning many hertz.
    clusters = []  # [centre index, members]
    for i, p, c, z in sorted(cands, key=lambda t: -t[3]):
        for cl in clusters:
            j = cl[0]
            if abs(i - j) <= 2 or abs(f[i] - f[j]) <= 0.02 * f[j]:
                cl[1].append((i, p, c))
                break
        else:
            clusters.append([i, [(i, p, c)]])
    return clusters


def _resonances(clusters, Hw, mags):
    """(indices, ranking prominences) of the clusters that are resonances: supported by a
    strict majority of the channels or their sum, or, with phase, lagging like a pole."""
    n_ch = mags.shape[0]
    need = n_ch // 2 + 1  # a strict majority of the channels
    has_phase = np.iscomplexobj(Hw) and np.any(Hw.imag != 0)
    idx, prom = [], []
    for _, cl in clusters:
        support = {c for _, _, c in cl}
        if n_ch in support or len(support) >= need:
            # rank by the channel sum's prominence where it sees the peak
            summed = [t for t in cl if t[2] == n_ch]
            best = max(summed or cl, key=lambda t: t[1])
            idx.append(best[0])
            prom.append(best[1] + (1e6 if summed else 0.0))
        elif has_phase:
            # a mode near the nodes of the other channels: the phase lag of a
            # pole tells it from a bump between two zeros, which does not lag
            poles = [t for t in cl if _phase_lags(Hw[t[2]], mags[t[2]], t[0])]
            if poles:
                best = max(poles, key=lambda t: t[1])
                idx.append(best[0])
                prom.append(best[1])
    return np.array(idx, dtype=int), np.array(prom)


def _phase_lags(h, mag, i, max_bins=10):
    """Whether the phase of h falls by >= pi/4 across the half-power band of the peak at i.

    The half-width k [bins] is the nearer -3 dB crossing of ``mag`` (at most
    max_bins; 2 if neither side falls that far before the grid ends), so the
    test spans the band where a pole turns the phase by about 90 deg.
    """
    level = mag[i] / np.sqrt(2.0)
    sides = []
    for step in (-1, 1):
        j = i + step
        while 0 <= j < mag.size and mag[j] >= level:
            j += step
        if 0 <= j < mag.size:
            sides.append(abs(j - i))
    k = min(min(sides), max_bins) if sides else 2
    lo, hi = max(i - k, 0), min(i + k, h.size - 1)
    phase = np.unwrap(np.angle(h[lo:hi + 1]))
    return phase[-1] - phase[0] <= -np.pi / 4


def _half_widths(f, idx, rel=0.05, min_bins=5):
    """Half-width [bins] of the +-rel*f window around each index (at least min_bins)."""
    df = np.gradient(f)
    return [max(int(round(rel * f[i] / df[i])), min_bins) for i in idx]


def _crossing(f, mag, i_peak, level, step):
    """Frequency where mag first falls below level walking from i_peak by step.

    NaN if the grid ends first or a higher peak is met (band unresolved).
    """
    peak = mag[i_peak]
    i = i_peak
    while 0 <= i + step < mag.size:
        j = i + step
        if mag[j] > peak:
            return np.nan
        if mag[j] < level:
            # linear interpolation between the last point above and the first below
            return f[i] + (level - mag[i]) * (f[j] - f[i]) / (mag[j] - mag[i])
        i = j
    return np.nan


def half_power_band(f, mag, i_peak):
    """Half-power (-3 dB) band around a peak.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies [Hz].
    mag : array_like, shape (n_f,)
        FRF magnitude (linear, not dB).
    i_peak : int
        Index of the peak, or of a point on its flank: the local maximum of
        ``mag`` uphill from it is used.

    Returns
    -------
    f_lo, f_hi : float
        Frequencies [Hz] where ``mag`` falls to ``mag[i_peak] / sqrt(2)``,
        linearly interpolated between grid points; NaN on a side where it
        does not fall that far before the grid ends or a higher peak. For a
        light, well-separated mode ``zeta ~ (f_hi - f_lo) / (2 f_r)``.
    """
    f = np.asarray(f, dtype=float)
    mag = np.asarray(mag, dtype=float)
    if mag.shape != f.shape or f.ndim != 1:
        raise InputError(_SRC, "mag", f"a 1-D magnitude array like f {f.shape}", got=mag.shape)
    if int(i_peak) != i_peak or not 0 <= i_peak < f.size:
        raise InputError(_SRC, "i_peak", f"an index in [0, {f.size - 1}]", got=i_peak)
    i = int(i_peak)
    # climb to the local maximum, so a peak index found on another curve
    # (e.g. the channel sum) still works for a single channel
    while True:
        j = max((i - 1, i, i + 1), key=lambda m: mag[m] if 0 <= m < mag.size else -np.inf)
        if j == i:
            break
        i = j
    level = mag[i] / np.sqrt(2.0)
    return _crossing(f, mag, i, level, -1), _crossing(f, mag, i, level, +1)


def peak_curve(f, H, i_peak):
    """The magnitude curve (a channel or the channel sum) that peaks at i_peak
    most sharply; the sum alone can show a weak mode only as a shoulder, and
    climbing that shoulder would measure the neighbouring mode instead."""
    mags = np.vstack([np.abs(np.atleast_2d(H)), _summed_mag(H)[None]])
    lo, hi = max(i_peak - 2, 1), min(i_peak + 3, f.size - 1)
    best, best_ratio = mags[-1], -np.inf
    for mag in mags:
        j = lo + int(np.argmax(mag[lo:hi]))
        if not (mag[j] >= mag[j - 1] and mag[j] >= mag[j + 1]):
            continue  # no local maximum here
        near = np.abs(f - f[j]) <= 0.05 * f[j]
        ratio = mag[j] / np.median(mag[near])
        if ratio > best_ratio:
            best, best_ratio = mag, ratio
    return best


def _peak_points(f, i_peak, band, k, min_points):
    """Indices within k * bandwidth of the peak, plus the nearest min_points."""
    f_r = f[i_peak]
    f_lo, f_hi = band
    # one unresolved side: assume a symmetric band
    if np.isnan(f_lo) and not np.isnan(f_hi):
        f_lo = 2 * f_r - f_hi
    if np.isnan(f_hi) and not np.isnan(f_lo):
        f_hi = 2 * f_r - f_lo
    dist = np.abs(f - f_r)
    near = np.argsort(dist, kind="stable")[:min_points]
    if np.isnan(f_lo):
        return near
    return np.union1d(np.flatnonzero(dist <= k * (f_hi - f_lo)), near)


def _band_points(f, bands):
    """Indices of f inside any of the user's (f_lo, f_hi) bands [Hz]."""
    keep = np.zeros(f.size, dtype=bool)
    for i, band in enumerate(bands):
        if len(band) != 2 or not band[0] < band[1]:
            raise InputError(_SRC, f"bands[{i}]", "a pair (f_lo, f_hi) in Hz with f_lo < f_hi",
                             got=band)
        keep |= (f >= band[0]) & (f <= band[1])
    return np.flatnonzero(keep)


MATCH_RATIO = 1.25  # a peak and a nominal mode this far apart in frequency are not paired


def match_modes(peaks_hz, model_hz, ratio=MATCH_RATIO):
    """Order-preserving pairs (i_peak, r_mode) of measured peaks and model modes [Hz].

    Both lists are sorted; the pairing keeps their order (modes of a structure do not
    swap between a model and its test) and minimises the summed |ln(f_peak / f_mode)|,
    an unpaired peak or mode costing ln(ratio) / 2, so that pairs further apart than
    ``ratio`` are never made (a dynamic programme, as for an edit distance).
    """
    p, q = np.log(np.asarray(peaks_hz, float)), np.log(np.asarray(model_hz, float))
    skip = 0.5 * np.log(ratio)
    m, n = p.size, q.size
    D = np.zeros((m + 1, n + 1))
    D[:, 0] = skip * np.arange(m + 1)
    D[0, :] = skip * np.arange(n + 1)
    for i in range(1, m + 1):
        pair = D[i - 1, :-1] + np.abs(p[i - 1] - q)
        pair[np.abs(p[i - 1] - q) > 2 * skip] = np.inf
        for j in range(1, n + 1):
            D[i, j] = min(pair[j - 1], D[i - 1, j] + skip, D[i, j - 1] + skip)
    pairs, i, j = [], m, n
    while i > 0 and j > 0:
        if D[i, j] == D[i - 1, j - 1] + abs(p[i - 1] - q[j - 1]) and \
                abs(p[i - 1] - q[j - 1]) <= 2 * skip:
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif D[i, j] == D[i - 1, j] + skip:
            i -= 1
        else:
            j -= 1
    return pairs[::-1]


def unresolved_points(f, peaks_hz, model_hz):
    """Indices of f where modes of the model lie that no measured peak matches.

    An unpaired mode (:func:`match_modes`) lies between the peaks paired with its
    neighbours (or a band edge): every point there is kept, since the data cannot
    say where in that interval its resonance is (modes closer than their half-power
    bandwidths merge into one peak; a mode one bin wide is not found as a peak).
    """
    f = np.asarray(f, float)
    pairs = match_modes(peaks_hz, model_hz)
    at = {r: peaks_hz[i] for i, r in pairs}
    keep = np.zeros(f.size, bool)
    for r in range(len(model_hz)):
        if r in at:
            continue
        lo = max([at[s] for s in at if s < r], default=-np.inf)
        hi = min([at[s] for s in at if s > r], default=np.inf)
        keep |= (f >= lo) & (f <= hi)
    return np.flatnonzero(keep)


def select_frequencies(f, H, k=1.0, coherence=None, min_coherence=None, bands=None,
                       n_peaks=None, min_points_per_peak=5, fmin=None, fmax=None,
                       prominence_db=6.0, min_level=None, sigma=None, model_hz=None):
    """Indices of the frequency points used for updating.

    For each resonance peak of ``sum_ch |H|`` (see `find_peaks`), keep the
    points with ``|f - f_r| <= k (f_hi - f_lo)`` where ``(f_lo, f_hi)`` is the
    half-power band, and always the ``min_points_per_peak`` points nearest
    ``f_r``. ``bands`` replaces this automatic choice (``k``, ``n_peaks``,
    ``fmin``, ``fmax`` are then ignored). Finally points whose coherence
    (minimum over channels) is below ``min_coherence`` are dropped.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies [Hz].
    H : array_like, shape (n_ch, n_f)
        FRFs.
    k : float
        Half-width of the kept region in half-power bandwidths.
    coherence : array_like, shape (n_ch, n_f) or (n_f,), optional
    min_coherence : float, optional
        Needs ``coherence``.
    bands : list of (float, float), optional
        Explicit frequency bands [Hz].
    n_peaks, fmin, fmax, prominence_db, min_level, sigma :
        Passed to `find_peaks`.
    min_points_per_peak : int
    model_hz : array_like, optional
        Natural frequencies [Hz] of the nominal model in the band: where the peaks
        found are fewer than its modes, the points where the unfound modes lie are
        kept too (:func:`unresolved_points`), so that no mode's information is lost.

    Returns
    -------
    ndarray of int
        Sorted unique indices into ``f``.
    """
    f, H = _check_fh(f, H)
    if bands is not None:
        idx = _band_points(f, bands)
    else:
        if not (np.isscalar(k) and k > 0):
            raise InputError(_SRC, "k", "a positive number of half-power bandwidths", got=k)
        if int(min_points_per_peak) != min_points_per_peak or min_points_per_peak < 1:
            raise InputError(_SRC, "min_points_per_peak", "a positive integer",
                             got=min_points_per_peak)
        peaks = find_peaks(f, H, n_peaks=n_peaks, prominence_db=prominence_db, min_level=min_level,
                           fmin=fmin, fmax=fmax, sigma=sigma)
        if peaks.size == 0:
            raise InputError(_SRC, "prominence_db", "a setting that finds at least one peak "
                             "(lower it, widen fmin/fmax or give explicit bands)",
                             got=prominence_db)
        inside = np.flatnonzero(band_mask(f, fmin, fmax))
        parts = [_peak_points(f, ip, half_power_band(f, peak_curve(f, H, ip), ip), k,
                              int(min_points_per_peak)) for ip in peaks]
        if model_hz is not None and len(model_hz) > peaks.size:
            parts.append(unresolved_points(f, f[np.sort(peaks)], np.sort(model_hz)))
        idx = np.intersect1d(np.concatenate(parts), inside)
    if min_coherence is not None:
        if coherence is None:
            raise InputError(_SRC, "coherence", "coherence values when min_coherence is given")
        coh = np.atleast_2d(np.asarray(coherence, dtype=float))
        if coh.shape[1] != f.size:
            raise InputError(_SRC, "coherence", f"shape (n_channels, {f.size})", got=coh.shape)
        idx = idx[np.min(coh, axis=0)[idx] >= min_coherence]
    if idx.size == 0:
        raise InputError(_SRC, "bands" if bands is not None else "min_coherence",
                         "settings that keep at least one frequency point")
    return np.unique(idx).astype(int)


def plot_selection(f, H, idx, path, channel_names=None):
    """Write a PNG of the dB magnitudes with the selected points marked.

    Parameters
    ----------
    f : array_like, shape (n_f,)
        Frequencies [Hz].
    H : array_like, shape (n_ch, n_f)
    idx : array_like of int
        Selected indices (from `select_frequencies`).
    path : str or path-like
        Output PNG file.
    channel_names : list of str, optional

    Returns
    -------
    path
    """
    # Figure + Agg canvas directly: no pyplot, so no global figure state.
    f, H = _check_fh(f, H)
    idx = np.asarray(idx, dtype=int)
    names = channel_names or [f"channel {i + 1}" for i in range(H.shape[0])]
    if len(names) != H.shape[0]:
        raise InputError(_SRC, "channel_names", f"{H.shape[0]} names", got=names)
    fig = Figure(figsize=(8, 4.5))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    with np.errstate(divide="ignore"):
        db = 20.0 * np.log10(np.abs(H))
    for i, name in enumerate(names):
        line, = ax.plot(f, db[i], lw=0.8, label=name)
        ax.plot(f[idx], db[i, idx], "o", ms=3, color=line.get_color())
    ax.set_xlabel("Frequency [Hz]")
    ax.set_ylabel("|H| [dB]")
    ax.set_title(f"Selected frequency points ({idx.size})")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    tmp = os.path.join(os.path.dirname(str(path)) or ".", ".tmp-" + os.path.basename(str(path)))
    fig.savefig(tmp, dpi=120, format="png")
    os.replace(tmp, path)  # atomic
    return path
