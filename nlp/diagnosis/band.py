"""Whole-band look at the residuals: every measured frequency with coherent data.

The fit uses windows around the resonances; a missing mode or an off-resonance
effect lives elsewhere. This module maps the noise-normalised residual
ln|H_x / H_a| over the whole measured band (third-octave bands x channel) and
reports unexplained resonances: peaks of the measured FRF (as an accelerance,
where every mode peaks) that the model does not show, with the channels that see
them.
"""

import numpy as np
from scipy.ndimage import median_filter
from scipy.signal import find_peaks

__all__ = ["band_mask", "local_sigma", "band_map", "extra_modes", "hot_spots"]

MIN_EXCESS = np.log(1.2)   # a peak the model misses by less than 20 % is not a new mode
PEAK_Z = 5.0               # a resonance rises this many local noise sigmas above the model
NEAR_MODEL = 0.02          # within 2 % of a model peak: a known mode, not an extra one
NEAR_ANTI = 0.05           # within 5 % of a model anti-resonance: a shifted zero, not a mode
MAX_SCATTER = 0.3          # local scatter of ln|H| above this: no coherent data there
HOT_Z2 = 25.0              # mean squared normalised residual over the channels (5 sigma rms):
                           # the model misses the data there by far more than the noise


def local_sigma(L, half=32, d2_factor=6.0):
    """Local noise of ln|H| along frequency: robust scatter of second differences
    (MAD x 1.4826 / sqrt(d2_factor)) in a moving window of 2 half + 1 points, one
    value per point.

    L : (n_ch, n_f) ln|H|. d2_factor : variance of a second difference of the errors in
    units of their point variance, 6 for independent bins, 2.5 for a Hann-windowed
    estimate (nlp.frf.noise.second_difference_factor): with correlated bins the second
    differences understate the point noise, and a 5-sigma peak test read with 6 would
    be a 3.2-sigma one. The moving median ignores a narrow resonance, whose second
    differences are large only over a few points.
    """
    d2 = np.abs(np.diff(L, 2, axis=1))
    d2 = np.pad(d2, ((0, 0), (1, 1)), mode="edge")
    med = median_filter(d2, size=(1, 2 * half + 1), mode="nearest")
    return np.maximum(1.4826 * med / np.sqrt(d2_factor), 1e-4)


def band_mask(f, coherence=None, fmin=None, min_coherence=None):
    """(n_ch, n_f) mask of the points a channel measured coherently (f > 0, f >= fmin,
    coherence >= min_coherence when the FRFs came with one)."""
    ok = f > 0
    if fmin is not None:
        ok &= f >= fmin
    if coherence is None:
        return np.broadcast_to(ok, (1, f.size))
    mask = ok[None, :] & np.isfinite(coherence)
    if min_coherence is not None:
        mask &= coherence >= min_coherence
    return mask


def band_map(f, r, mask, fitted=None, per_octave=3):
    """Mean squared normalised residual per channel x fractional-octave band.

    f : (n_f,) Hz; r : (n_ch, n_f) residual / noise (nan where not measured);
    mask : (n_ch, n_f) or (1, n_f) coherent points; fitted : optional index array of
    points used in the fit. Returns a list of cells {channel index, band_hz,
    chi2, points, fitted_points}.
    """
    mask = np.broadcast_to(mask, r.shape)
    used = mask.any(axis=0)
    if not used.any():
        return []
    lo, hi = f[used].min(), f[used].max()
    n_b = max(1, int(np.ceil(per_octave * np.log2(hi / lo) + 1e-9)))
    edges = lo * (hi / lo) ** (np.arange(n_b + 1) / n_b)
    fit_mask = np.zeros(f.size, bool)
    if fitted is not None:
        fit_mask[np.asarray(fitted, int)] = True
    cells = []
    for b in range(n_b):
        inb = (f >= edges[b]) & ((f < edges[b + 1]) if b < n_b - 1 else (f <= edges[b + 1]))
        for c in range(r.shape[0]):
            sel = inb & mask[c]
            if sel.any():
                cells.append({"channel": c, "band_hz": [float(edges[b]), float(edges[b + 1])],
                              "chi2": float(np.mean(r[c, sel] ** 2)), "points": int(sel.sum()),
                              "fitted_points": int((sel & fit_mask).sum())})
    return cells


def _persists(r, i, size):
    """True when the residual departs from its local median by size/2 or more, with one
    sign, on at least two of the points i-1, i, i+1: a resonance spans more than one
    bin (or shifts the level after it), a noise spike does not."""
    lo, hi = max(i - 20, 0), min(i + 21, r.size)
    dev = r[max(i - 1, 0):i + 2] - np.median(r[lo:hi])
    return max(int(np.sum(dev >= size / 2)), int(np.sum(dev <= -size / 2))) >= 2


def near(fa, fb, resolution=0.0):
    """Whether two frequencies [Hz] are one mode: within NEAR_MODEL of each other, or
    within the estimate's resolution [Hz] (resolution.estimate_resolution), since a peak's
    bin can move by that much between channels. Below about 2 Hz on a 4096-point Welch
    estimate at 100 Hz, 2 % is less than one bin."""
    return np.abs(np.asarray(fa, float) - fb) <= max(NEAR_MODEL * fb, resolution)


def extra_modes(f, L_meas, L_model, sigma, mask, d2_factor=6.0, resolution=0.0):
    """Resonances in the measurement that the model does not have.

    f : (n_f,) Hz; L_meas, L_model : (n_ch, n_f) ln|H| of each channel as an
    accelerance (measured, model); sigma : (n_ch, n_f) noise of ln|H|; mask : coherent
    points. A measured peak (prominence >= max(ln 1.2, PEAK_Z sigma)) is
    unexplained on a channel when the measurement exceeds the model there by more
    than max(ln 1.2, PEAK_Z sigma) and the model has no peak within 2 % or the
    estimate's resolution [Hz] (:func:`near`). Peaks on several channels that near are
    one mode. A step or dip of a lightly damped mode
    is read from second differences, whose noise is sqrt(d2_factor) sigma (local_sigma).
    Returns [{frequency_hz, channels
    (indices), excess (ln ratio per channel)}], sorted by frequency.
    """
    mask = np.broadcast_to(mask, L_meas.shape)
    hits = []
    for c in range(L_meas.shape[0]):
        ok = mask[c]
        if ok.sum() < 5:
            continue
        idx = np.nonzero(ok)[0]
        lm = L_meas[c, idx]
        sig = sigma[c, idx]
        r = lm - L_model[c, idx]
        peaks, props = find_peaks(lm, prominence=MIN_EXCESS, wlen=41)
        peaks = peaks[props["prominences"] >= PEAK_Z * sig[peaks]]
        mpk, _ = find_peaks(L_model[c, idx], prominence=0.1)
        f_model = f[idx][mpk]
        for p in peaks:
            fp = f[idx][p]
            if f_model.size and np.any(near(f_model, fp, resolution)):
                continue
            excess = lm[p] - L_model[c, idx][p]
            if excess > max(MIN_EXCESS, PEAK_Z * sig[p]) and _persists(r, p, excess):
                hits.append((fp, c, float(excess)))
        # a lightly damped mode can also show as a sharp step or dip (its peak falls between
        # two bins, or the mode's phase makes it cancel the rest of the response): a second
        # difference of ln|H| that the model does not have
        d2 = np.diff(lm, 2) - np.diff(L_model[c, idx], 2)
        thr = np.maximum(MIN_EXCESS, PEAK_Z * np.sqrt(d2_factor) * sig[1:-1])
        sharp, _ = find_peaks(np.abs(d2), height=0.0, distance=5)
        apk, _ = find_peaks(-L_model[c, idx], prominence=0.1)
        f_anti = f[idx][apk]  # the model's anti-resonances: a shifted one is not a new mode
        for q in sharp[np.abs(d2[sharp]) > thr[sharp]]:
            fp = f[idx][q + 1]
            if f_model.size and np.any(near(f_model, fp, resolution)):
                continue
            if f_anti.size and np.min(np.abs(f_anti - fp)) <= NEAR_ANTI * fp:
                continue
            if _persists(r, q + 1, abs(d2[q])):
                hits.append((fp, c, float(abs(d2[q]))))
    hits.sort()
    modes = []
    for fp, c, ex in hits:
        if modes and near(modes[-1]["_f"][-1], fp, resolution):
            m = modes[-1]
        else:
            m = {"_f": [], "channels": [], "excess": []}
            modes.append(m)
        m["_f"].append(fp)
        if c not in m["channels"]:
            m["channels"].append(c)
            m["excess"].append(ex)
    out = []
    for m in modes:
        best = int(np.argmax(m["excess"]))
        out.append({"frequency_hz": float(np.median(m["_f"])), "channels": m["channels"],
                    "excess": m["excess"], "strongest": m["channels"][best]})
    return out


def hot_spots(f, r, mask, exclude=(), z2=HOT_Z2, n_max=2, separation=0.2, smooth=5):
    """Frequencies [Hz] where the model misses the data most, away from the fitted points.

    f : (n_f,) Hz; r : (n_ch, n_f) residual / noise; mask : coherent points; exclude :
    indices of the fitted points. The mean of r^2 over the channels that measured a
    point, averaged over ``smooth`` points, is read at its largest values off the
    fitted points, at most ``n_max`` of them, ``separation`` (relative) apart, each above
    ``z2``. An effect between the resonances (an appendage tuned away from every mode)
    shows there even when the measurement has no peak of its own (a channel mean z^2 over
    a hundred around an appendage whose resonance merges with the structure's response;
    see docs/method/diagnosis.md).
    """
    mask = np.broadcast_to(mask, r.shape)
    rr = np.where(mask, r ** 2, 0.0)
    cnt = mask.sum(axis=0)
    q = np.where(cnt > 0, rr.sum(axis=0) / np.maximum(cnt, 1), np.nan)
    q[np.asarray(exclude, int)] = np.nan
    ok = np.isfinite(q)
    k = np.ones(smooth)
    num = np.convolve(np.where(ok, q, 0.0), k, mode="same")
    den = np.convolve(ok.astype(float), k, mode="same")
    qs = np.where(ok & (den >= (smooth + 1) // 2), num / np.maximum(den, 1), -np.inf)
    out = []
    while len(out) < n_max:
        i = int(np.argmax(qs))
        if not np.isfinite(qs[i]) or qs[i] < z2:
            break
        out.append(float(f[i]))
        qs[np.abs(f / f[i] - 1.0) <= separation] = -np.inf
    return out
