"""FRF estimation from measured input/output time histories.

The FRF maps the input ``x`` to the outputs ``y`` as ``Y = H X`` with numpy's
FFT sign (``exp(-j w t)`` in the forward transform). Spectra are Welch
averages (``scipy.signal.welch`` / ``scipy.signal.csd``); ``csd(x, y)``
averages ``conj(X) Y``, so ``S_xy = H S_xx`` for a noise-free system.
"""

from dataclasses import dataclass

import numpy as np
from scipy import signal

from nlp.errors import InputError

__all__ = ["FRFEstimate", "ESTIMATORS", "estimate_frf"]

ESTIMATORS = ("H1", "H2", "Hv")


@dataclass(frozen=True)
class FRFEstimate:
    """An estimated FRF set.

    Attributes
    ----------
    f : ndarray, shape (n_f,)
        Frequencies [Hz].
    H : ndarray, shape (n_ch, n_f), complex
        FRF of each output channel with respect to the input
        [output unit / input unit].
    coherence : ndarray, shape (n_ch, n_f)
        Ordinary coherence ``|S_xy|^2 / (S_xx S_yy)``, in [0, 1].
    estimator : str
        ``"H1"``, ``"H2"`` or ``"Hv"``.
    """

    f: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    estimator: str


def _as_signals(x, y, source):
    """Check and shape the records: x (N,), y (n_ch, N), all finite."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.ndim != 1:
        raise InputError(source, "x", "a 1-D input record", got=f"shape {x.shape}")
    if y.ndim == 1:
        y = y[np.newaxis, :]
    if y.ndim != 2:
        raise InputError(source, "y", "outputs shaped (n_channels, N)", got=f"shape {y.shape}")
    if y.shape[1] != x.size:
        raise InputError(source, "y", f"{x.size} samples per channel, as many as the input x",
                         got=f"shape {y.shape}")
    if not np.all(np.isfinite(x)):
        raise InputError(source, "x", "finite samples (no NaN or inf)",
                         got=f"non-finite value at sample {int(np.argmin(np.isfinite(x)))}")
    bad = ~np.isfinite(y)
    if bad.any():
        ch, n = np.argwhere(bad)[0]
        raise InputError(source, f"y[{ch}]", "finite samples (no NaN or inf)",
                         got=f"non-finite value at sample {n}")
    return x, y


def _default_nperseg(n):
    """Largest power of two <= N/8, so Welch averages ~15 half-overlapping segments."""
    return int(2 ** np.floor(np.log2(max(n // 8, 1))))


def _check_segments(n, nperseg, noverlap, source):
    """Resolve the Welch segment length and overlap, in samples."""
    if nperseg is None:
        nperseg = _default_nperseg(n)
    if int(nperseg) != nperseg or nperseg < 2:
        raise InputError(source, "nperseg", "an integer number of samples >= 2", got=nperseg)
    nperseg = int(nperseg)
    if nperseg > n:
        raise InputError(source, "nperseg", f"at most the record length ({n} samples)",
                         got=nperseg)
    if noverlap is not None and not (0 <= noverlap < nperseg):
        raise InputError(source, "noverlap", f"an integer in [0, nperseg={nperseg})", got=noverlap)
    return nperseg, noverlap


def _combine(s_xx, s_yy, s_xy, estimator):
    """FRF from averaged spectra; zero denominators give NaN, not a warning."""
    with np.errstate(divide="ignore", invalid="ignore"):
        h1 = s_xy / s_xx  # paper Eqn 20
        if estimator == "H1":
            return h1
        h2 = s_yy / np.conj(s_xy)  # S_yy / S_yx
        if estimator == "H2":
            return h2
        # Hv: geometric mean of |H1| and |H2|, with the H1 phase (H1 and H2
        # share the phase of S_xy for a single input, so this equals sqrt(H1 H2)).
        return np.sqrt(np.abs(h1) * np.abs(h2)) * np.exp(1j * np.angle(h1))


def estimate_frf(x, y, fs, estimator="H1", nperseg=None, noverlap=None, window="hann",
                 detrend="constant", *, source="<data>"):
    """Estimate FRFs from an input record and output records.

    Parameters
    ----------
    x : array_like, shape (N,)
        Input record (ground acceleration [m/s^2] or force [N]).
    y : array_like, shape (n_ch, N) or (N,)
        Output records, same sampling as ``x``.
    fs : float
        Sampling frequency [Hz].
    estimator : {"H1", "H2", "Hv"}
        ``"H1"``: ``S_xy / S_xx`` (paper Eqn 20; unbiased by output noise).
        ``"H2"``: ``S_yy / S_yx`` (unbiased by input noise).
        ``"Hv"``: ``sqrt(|H1| |H2|) exp(j angle(H1))``, the geometric mean of
        the two magnitudes with the H1 phase (a simple stand-in for the
        total-least-squares Hv; it lies between ``|H1|`` and ``|H2|``).
    nperseg : int, optional
        Welch segment length [samples]. Default: the largest power of two not
        above ``N / 8``.
    noverlap : int, optional
        Overlap [samples]; default ``nperseg // 2`` (scipy's default).
    window, detrend :
        Passed to ``scipy.signal.welch`` / ``csd``.
    source : str, optional
        Name used in error messages (the data file, if there is one).

    Returns
    -------
    FRFEstimate
        ``f`` [Hz] (0 to fs/2), ``H`` (n_ch, n_f), ``coherence`` (n_ch, n_f).

    Raises
    ------
    InputError
        Mismatched lengths, non-finite samples, bad segment settings,
        unknown estimator.
    """
    if estimator not in ESTIMATORS:
        raise InputError(source, "estimator", f"one of {', '.join(ESTIMATORS)}", got=estimator)
    if not (np.isscalar(fs) and np.isfinite(fs) and fs > 0):
        raise InputError(source, "fs", "a positive sampling frequency in Hz", got=fs)
    x, y = _as_signals(x, y, source)
    nperseg, noverlap = _check_segments(x.size, nperseg, noverlap, source)
    kw = dict(fs=fs, window=window, nperseg=nperseg, noverlap=noverlap, detrend=detrend)
    f, s_xx = signal.welch(x, **kw)
    _, s_yy = signal.welch(y, axis=-1, **kw)
    _, s_xy = signal.csd(x[np.newaxis, :], y, axis=-1, **kw)
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.abs(s_xy) ** 2 / (s_xx * s_yy)
    return FRFEstimate(f=f, H=_combine(s_xx, s_yy, s_xy, estimator),
                       coherence=np.clip(coh, 0.0, 1.0), estimator=estimator)
