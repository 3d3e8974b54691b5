"""The window of a windowed-average FRF estimate (Welch, an analyzer's average): how many
independent averages it gives, and how its spectral kernel smooths and biases the FRF.

Averaged spectra are the true ones smoothed by the window's power kernel |W(nu)|^2, of
second moment m2 [bins^2] (:func:`kernel_moment`); the model can carry that smoothing as
three taps (:func:`smoothing_taps`, :func:`estimator_kernel`), or the noise model counts
the bias it leaves at sharp peaks, Re(m2 H''/(2H)) (:func:`resolution_bias`).
"""

import math

import numpy as np
from scipy import signal

from nlp.frf.estimate import default_nperseg

__all__ = ["FILE_NPERSEG", "welch_averages", "kernel_moment", "smoothing_taps", "estimator_kernel",
           "resolution_bias", "file_resolution_bias2"]

# segment length [samples] taken for an FRF file, which does not state its own: the taps and
# kernel moments converge with it
FILE_NPERSEG = 1024


def welch_averages(n, nperseg, noverlap=None, window="hann"):
    """Number of Welch segments and the effective number of independent averages.

    Overlapping segments are correlated; for a stationary signal the variance
    of the averaged spectrum is (1/n_d) [1 + 2 sum_j (1 - j/n_d) rho_j^2], with
    rho_j = sum w_i w_(i+jS) / sum w_i^2 the overlap correlation of the window
    at a shift of j steps S (Welch 1967).

    Parameters
    ----------
    n : int
        Record length [samples].
    nperseg : int
        Segment length [samples].
    noverlap : int, optional
        Overlap [samples]; default nperseg // 2 (scipy's).
    window : str
        scipy window name.

    Returns
    -------
    n_d : int
        Number of segments.
    n_eff : float
        Effective number of independent averages (<= n_d).
    """
    nperseg = int(min(nperseg, n))
    noverlap = nperseg // 2 if noverlap is None else int(noverlap)
    step = max(nperseg - noverlap, 1)
    n_d = max((n - nperseg) // step + 1, 1)
    w = signal.get_window(window, nperseg)
    w2 = float(w @ w)
    acc = 1.0
    for j in range(1, n_d):
        if j * step >= nperseg:
            break
        rho = float(w[j * step:] @ w[:nperseg - j * step]) / w2
        acc += 2 * (1 - j / n_d) * rho ** 2
    return n_d, n_d / acc


def kernel_moment(window, nperseg):
    """Second moment [bins^2] of the window's spectral (power) kernel.

    By Parseval, m2 = L^2 sum (w_(i+1) - w_i)^2 / (4 pi^2 sum w_i^2); Hann: 1/3.
    """
    w = signal.get_window(window, int(nperseg))
    dw = np.diff(np.concatenate([[0.0], w, [0.0]]))
    return nperseg ** 2 * float(dw @ dw) / (4 * math.pi ** 2 * float(w @ w))


def smoothing_taps(window, nperseg=FILE_NPERSEG):
    """The averaged estimate's view of an FRF as three taps: (h [bins], a).

    A windowed average (Welch, an analyzer's FRF) estimates the true FRF smoothed by
    the window's power kernel |W(nu)|^2 (flat input spectrum). The three taps
    a H(f - h df) + (1 - 2a) H(f) + a H(f + h df) have the kernel's second and
    fourth moments (h^2 = m4 / m2, a = m2^2 / (2 m4)), so they carry its effect on a
    peak to fifth order; Hann: h = 1 bin, a = 1/6.
    """
    w = signal.get_window(window, int(nperseg))
    L, P = w.size, 16
    K = np.abs(np.fft.fft(w, L * P)) ** 2
    K /= K.sum()
    nu = np.fft.fftfreq(L * P, d=1.0 / L)
    m2, m4 = float(nu ** 2 @ K), float(nu ** 4 @ K)
    return math.sqrt(m4 / m2), m2 ** 2 / (2 * m4)


def estimator_kernel(cfg, f, records=None, coherence=None, n_averages=None):
    """Taps (h [rad/s], a) of the case's FRF estimate (:func:`smoothing_taps`), or None.

    A Welch average of the case's own time histories smooths the FRF by its window,
    which is then known exactly. A whole transient in one segment (``nperseg: all``)
    is not smoothed. A stored FRF file that carries its coherence and number of
    averages is a windowed average too, with ``data.window`` (default Hann) at the
    file's resolution; its coherence holds the scatter that the window's leakage adds
    at sharp peaks, so the three taps leave nothing the noise model misses (blind
    null files: coherence variance against the three-tap smoothed truth, mean z^2
    0.76-1.22, the same as against the exact kernel). A file without coherence is an
    analyzer's average as well (``data.window``; ``none`` when it is not): it carries
    the kernel too, and the noise model keeps part of the resolution bias for the
    leakage scatter that its scatter level cannot see (:func:`nlp.frf.noise.noise_model`). Windows
    without finite kernel moments (rectangular) and ``window: none`` carry no kernel.

    coherence, n_averages : of a stored FRF file (None for time histories).
    """
    d = cfg.data
    f = np.asarray(f, float)
    from_records = records is not None and "__input__" in records.data
    # a file with coherence states its averages (one: not an average); without, it is
    # taken as an analyzer's average unless data.window says none
    averaged_file = records is None and (coherence is None or float(n_averages or 1) > 1)
    if ((not from_records and not averaged_file) or d.nperseg == "all"
            or d.window in ("boxcar", "rectangular", "none") or f.size < 5):
        return None
    df = np.diff(f)
    if np.max(np.abs(df - df.mean())) > 1e-6 * abs(df.mean()):
        return None
    if from_records:
        nperseg = d.nperseg or default_nperseg(records.t.size)
    else:   # the file's segment length is not stated; the taps converge with it
        nperseg = FILE_NPERSEG
    h, a = smoothing_taps(d.window, nperseg)
    return 2 * math.pi * h * float(df.mean()), a


def resolution_bias(H, m2):
    """Bias of ln|H| of an averaged estimate from the finite resolution.

    The averaged spectra are the true ones smoothed by the window's power
    kernel: S_xy ~ H S_xx + (m2 / 2) (H S_xx)'' for a smooth input spectrum,
    so ln|H1| is off by Re(m2 H'' / (2 H)) (derivatives per bin). H'' is taken
    from the measured H by second differences (large only at sharp peaks).
    """
    H = np.atleast_2d(np.asarray(H, complex))
    d2 = np.zeros_like(H)
    d2[:, 1:-1] = H[:, 2:] - 2 * H[:, 1:-1] + H[:, :-2]
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.real(0.5 * m2 * d2 / H)
    return np.nan_to_num(b, nan=0.0, posinf=0.0, neginf=0.0)



def file_resolution_bias2(f, H, window="hann"):
    """Squared resolution bias of ln|H| of an FRF averaged with ``window`` on a uniform
    grid; 0 for ``window: none`` (an FRF not estimated by windowed averaging, e.g.
    stepped sine or a frequency-domain simulation) or a non-uniform grid."""
    f = np.asarray(f, float)
    if window == "none" or f.size < 5:
        return 0.0
    df = np.diff(f)
    if np.max(np.abs(df - df.mean())) > 1e-6 * abs(df.mean()):
        return 0.0
    return resolution_bias(H, kernel_moment(window, FILE_NPERSEG)) ** 2
