"""Which measured frequencies the objective uses: half-power windows around the peaks of
the detection form (every channel as an accelerance), given bands or points, or all,
inside fmin-fmax and above the coherence floor."""

import numpy as np

from nlp.case.checks import check_points_inside
from nlp.errors import InputError
from nlp.frf.forms import POWER
from nlp.frf.freqsel import select_frequencies
from nlp.frf.reference import BASE_DOF
from nlp.model.damping import band_modes

__all__ = ["detection_form", "select_points", "half_power_points", "model_frequencies", "selectable",
           "detection_noise"]


def detection_form(f, H, channels, excitation):
    """Each channel as an accelerance, absolute for ground input (-w^2 H + 1 for a
    receptance): every mode peaks there, while the 1/w^2 fall of a receptance
    can hide a high mode of a base-excited frame."""
    jw = 2j * np.pi * f
    out = np.empty_like(H)
    for c, ch in enumerate(channels):
        out[c] = H[c] * jw ** (2 - POWER[ch.output])
        if excitation == "ground" and ch.output != "absolute_accelerance":
            out[c] += 1.0
    return out


def select_points(cfg, f, H, channels, excitation, coherence=None, sigma=None, model_hz=None,
                  source=None):
    """Indices into f of the points the objective uses, by frequencies.method; sigma: std
    of ln|H| (n_ch, n_f) for the half-power method; model_hz: the nominal model's natural
    frequencies [Hz] (half-power: where fewer peaks are found, the unfound modes' points
    are kept, :func:`nlp.frf.freqsel.unresolved_points`); source: the data file H came
    from, named in an error (default: the case's data.file)."""
    fc = cfg.frequencies
    if fc.method == "all":
        mask = np.ones(f.size, bool)
        if fc.fmin is not None:
            mask &= f >= fc.fmin
        if fc.fmax is not None:
            mask &= f <= fc.fmax
        idx = np.nonzero(mask)[0]
    elif fc.method == "points":
        check_points_inside(cfg, f)
        idx = np.unique([int(np.argmin(np.abs(f - p))) for p in fc.points])
    else:
        check_points_inside(cfg, f)
        try:
            idx = half_power_points(cfg, f, H, channels, excitation, coherence, sigma, model_hz)
        except InputError as exc:  # freqsel names its argument; say which case key it is
            raise _frequency_error(cfg, f, exc, source or cfg.data.file) from None
    return _nonempty(cfg, f, idx)


_FREQ_KEYS = {"k", "bands", "points", "fmin", "fmax", "n_peaks", "min_points_per_peak",
              "min_coherence"}


def _frequency_error(cfg, f, exc, source):
    """A freqsel error named by a key that exists in the case file; source: the data file."""
    if exc.key in _FREQ_KEYS:
        return InputError(cfg.path, f"frequencies.{exc.key}", exc.expected, exc.got)
    if exc.key == "prominence_db":  # no resonance peak: the data, not a setting, is the cause
        return InputError(cfg.path, "frequencies.method", "a method the data allow: half_power "
                          f"needs a resonance peak, and {source} shows none in "
                          f"{f[0]:g}-{f[-1]:g} Hz (check its record length and input, or use "
                          "bands or all)", cfg.frequencies.method)
    return InputError(cfg.path, "frequencies.method", f"{exc.expected} (from {exc.key})", exc.got)


def half_power_points(cfg, f, H, channels, excitation, coherence, sigma=None, model_hz=None):
    """Half-power selection on the detection form; sigma: std of ln|H| (n_ch, n_f), so
    that a peak must stand out of the noise (carried over to the detection form)."""
    fc = cfg.frequencies
    # a base sensor sees the modes only through a flexible base: peaks are looked for
    # on the structure's channels
    rows = [c for c, ch in enumerate(channels) if ch.dof != BASE_DOF] or list(range(len(channels)))
    channels, H = [channels[c] for c in rows], H[rows]
    coherence = None if coherence is None else coherence[rows]
    sigma = None if sigma is None else sigma[rows]
    det = detection_form(f, H, channels, excitation)
    sigma = detection_noise(f, H, det, channels, sigma)
    return select_frequencies(f, det, k=fc.k,
                              coherence=coherence, min_coherence=fc.min_coherence,
                              bands=list(fc.bands) or None, n_peaks=fc.n_peaks,
                              min_points_per_peak=fc.min_points_per_peak, fmin=fc.fmin,
                              fmax=fc.fmax, sigma=sigma,
                              model_hz=None if fc.n_peaks is not None else model_hz)


def model_frequencies(model, f_lo, f_hi):
    """Undamped natural frequencies [Hz] of the nominal model between f_lo and f_hi."""
    n = model.n
    count = min(n, 8)
    while True:  # widen the eigen-solve until it passes the band's top
        omega, _ = band_modes(model.M0, model.K0, count)
        if omega[-1] > 2 * np.pi * f_hi or count >= n:
            break
        count = n if 2 * count >= n - 1 else 2 * count  # n - 1 and more: the dense solver
    fr = omega / (2 * np.pi)
    return fr[(fr >= f_lo) & (fr <= f_hi)]


def selectable(cfg, f, channels, coherence):
    """(n_f,) mask of the points the half-power selection may keep: f inside
    fmin-fmax, and coherence >= min_coherence on every structure channel (the
    rules `half_power_points` applies). Windows added around other frequencies (the
    diagnosis's hot spots) keep to it, so no point the case rules out is fitted."""
    fc = cfg.frequencies
    ok = (f >= (-np.inf if fc.fmin is None else fc.fmin)) & \
         (f <= (np.inf if fc.fmax is None else fc.fmax))
    if fc.min_coherence is not None and coherence is not None:
        rows = [c for c, ch in enumerate(channels) if ch.dof != BASE_DOF] \
            or list(range(len(channels)))
        ok &= np.min(np.asarray(coherence)[rows], axis=0) >= fc.min_coherence
    return ok


def detection_noise(f, H, det, channels, sigma):
    """Std of ln|det| from the std of ln|H| (n_ch, n_f): the jw powers leave it
    unchanged, the +1 of a relative channel under ground input scales it by
    |jw^p H| / |det|. None stays None."""
    if sigma is None:
        return None
    jw = 2j * np.pi * f
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.array([np.abs(H[c] * jw ** (2 - POWER[ch.output])) / np.abs(det[c])
                          for c, ch in enumerate(channels)])
    return sigma * np.nan_to_num(ratio, nan=1.0, posinf=1.0)


def _nonempty(cfg, f, idx):
    idx = np.asarray(idx, int)
    idx = idx[f[idx] > 0]
    if idx.size == 0:
        raise InputError(cfg.path, "frequencies", "settings that select at least one frequency "
                         f"point inside the data's range {f[0]:g}-{f[-1]:g} Hz")
    return idx
