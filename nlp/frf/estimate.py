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

__all__ = ["FRFEstimate", "ESTIMATORS", "estimate_frf", "hv_tls", "default_nperseg"]

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
    n_averages : int
        Number of Welch segments averaged, over all records: the ``n_d`` of
        the coherence-based noise of ``ln|H|`` (Bendat & Piersol).
    """

    f: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    estimator: str
    n_averages: int = 1


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


def default_nperseg(n):
    """Largest power of two <= N/8, so Welch averages ~15 half-overlapping segments."""
    return int(2 ** np.floor(np.log2(max(n // 8, 1))))


def _check_segments(n, nperseg, noverlap, source):
    """Resolve the Welch segment length and overlap, in samples."""
    if nperseg is None:
        nperseg = default_nperseg(n)
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
        return hv_tls(s_xx, s_yy, s_xy)


def hv_tls(s_xx, s_yy, s_xy):
    """Hv: the total-least-squares FRF of one input and one output.

    Hv = -v_x / v_y for the eigenvector v of the smallest eigenvalue of
    ``[[S_xx, S_xy], [S_yx, S_yy]]`` (the estimator pyFRF and the modal-testing
    literature call Hv): it minimises ``E|Y - H X|^2 / (1 + |H|^2)``, so noise on
    input and output weigh alike. Closed form of the 2 x 2 eigenproblem, from
    whichever row avoids cancellation. Units as ``S_xy / S_xx``; unlike H1 and H2
    the result depends on the relative scaling of x and y (both in SI here).
    """
    s_xx, s_yy, s_xy = np.broadcast_arrays(s_xx, s_yy, s_xy)
    diff = np.real(s_xx - s_yy)
    root = np.sqrt(diff ** 2 + 4 * np.abs(s_xy) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        first = 2 * s_xy / (diff + root)              # row 1: (S_xx - lam) v_x + S_xy v_y = 0
        second = (-diff + root) / (2 * np.conj(s_xy))  # row 2: S_yx v_x + (S_yy - lam) v_y = 0
    return np.where(diff >= 0, first, second)


def _segments(n, nperseg, noverlap):
    """Welch segments scipy averages in a record of n samples."""
    step = nperseg - (nperseg // 2 if noverlap is None else noverlap)
    return (n - nperseg) // step + 1


def estimate_frf(x, y, fs, estimator="H1", nperseg=None, noverlap=None, window="hann",
                 detrend="constant", *, source="<data>"):
    """Estimate FRFs from an input record and output records.

    Parameters
    ----------
    x : array_like, shape (N,), or a list of such records
        Input record (ground acceleration [m/s^2] or force [N]). A list holds
        several records of one test: their Welch segments are averaged
        together (H1 over all segments of all records).
    y : array_like, shape (n_ch, N) or (N,), or a list matching ``x``
        Output records, same sampling as ``x``.
    fs : float
        Sampling frequency [Hz].
    estimator : {"H1", "H2", "Hv"}
        ``"H1"``: ``S_xy / S_xx`` (paper Eqn 20; unbiased by output noise).
        ``"H2"``: ``S_yy / S_yx`` (unbiased by input noise).
        ``"Hv"``: total least squares (`hv_tls`), for noise on both.
    nperseg : int, optional
        Welch segment length [samples]. Default: the largest power of two not
        above ``N / 8`` (N of the shortest record).
    noverlap : int, optional
        Overlap [samples]; default ``nperseg // 2`` (scipy's default).
    window, detrend :
        Passed to ``scipy.signal.welch`` / ``csd``.
    source : str, optional
        Name used in error messages (the data file, if there is one).

    Returns
    -------
    FRFEstimate
        ``f`` [Hz] (0 to fs/2), ``H`` (n_ch, n_f), ``coherence`` (n_ch, n_f),
        ``n_averages`` (segments averaged).

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
    several = isinstance(x, (list, tuple))
    xs, ys = (list(x), list(y)) if several else ([x], [y])
    if not xs or len(xs) != len(ys):
        raise InputError(source, "records", "one output set per input record",
                         got=f"{len(xs)} inputs, {len(ys)} outputs")
    pairs = [_as_signals(xi, yi, source) for xi, yi in zip(xs, ys)]
    if len({p[1].shape[0] for p in pairs}) > 1:
        raise InputError(source, "records", "the same channels in every record")
    nperseg, noverlap = _check_segments(min(p[0].size for p in pairs), nperseg, noverlap, source)
    kw = dict(fs=fs, window=window, nperseg=nperseg, noverlap=noverlap, detrend=detrend)
    s_xx = s_yy = s_xy = 0.0
    n_avg = 0
    for xi, yi in pairs:
        # scipy averages the segments of one record; weight each record by its count
        k = _segments(xi.size, nperseg, noverlap)
        f, sxx = signal.welch(xi, **kw)
        _, syy = signal.welch(yi, axis=-1, **kw)
        _, sxy = signal.csd(xi[np.newaxis, :], yi, axis=-1, **kw)
        s_xx, s_yy, s_xy, n_avg = s_xx + k * sxx, s_yy + k * syy, s_xy + k * sxy, n_avg + k
    s_xx, s_yy, s_xy = s_xx / n_avg, s_yy / n_avg, s_xy / n_avg
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.abs(s_xy) ** 2 / (s_xx * s_yy)
    return FRFEstimate(f=f, H=_combine(s_xx, s_yy, s_xy, estimator),
                       coherence=np.clip(coh, 0.0, 1.0), estimator=estimator, n_averages=n_avg)
