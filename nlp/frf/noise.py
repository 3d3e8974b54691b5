"""Noise of a measured FRF: the variance of ln|H| and of its phase, per channel and frequency.

The residuals of the updating are ln|H_a| - ln|H_x| (and the phase, for the
complex residual); dividing them by the standard deviation of the estimate
makes the objective a chi-square. That standard deviation depends on how the
FRF was obtained (the "route"), and it varies along frequency by two orders of
magnitude (small at the peaks, large in low-response shoulders), so it is
derived per point from the data themselves:

``transient``  one segment of a record that starts and ends at rest (chirp,
               impact): H = Y / X, with white-or-coloured noise of spectral
               density S_nx on the input and S_ny on an output. To first order
               (errors in variables),

                   Var ln|H| = Var arg H = (S_ny / |Y|^2 + S_nx / |X|^2) / 2,

               with |X|^2, |Y|^2 the record's periodograms (same window) and
               the noise spectra measured in its rest portions (where the input
               is quiet and the response has died out).
``welch``      averaged spectra, H1 = S_xy / S_xx (paper Eqn 20):
               Var ln|H1| = (1 - g^2) / (2 n g^2) (Bendat & Piersol), with g^2 the
               ordinary coherence (it already holds the input noise) and n the
               number of averages corrected for the overlap of the windows;
               plus the square of the resolution bias at sharp peaks (the
               window's kernel smooths the spectra: Re(m2 H''/(2H))).
               With input noise H1 is biased low by ln(1 + S_nx/S_uu); when the
               rest portions give S_nx, that bias is added to the variance.
``frf_coherence``  an FRF file that carries its coherence (and the averages).
               For both FRF-file routes, the model carries the kernel of the
               analyzer's window (``data.window``, default Hann; ``none`` for an FRF
               that was not estimated by windowed averaging) at the file's own
               resolution (:func:`estimator_kernel`), as for Welch.
``scatter``    an FRF file without coherence, or records without a rest
               portion: the robust local scatter of second differences of
               ln H along frequency (Re: magnitude, Im: phase), in a sliding
               window, so the level still follows the frequency. For an averaged
               file, LEAKAGE_KEEP of the squared resolution bias is added for the
               leakage scatter at sharp peaks, which a level over 51 bins misses.

For a complex-circular error the magnitude and phase variances are equal; the
model returns both.
"""

from dataclasses import dataclass
import math

import numpy as np
from scipy import signal
from scipy.ndimage import uniform_filter1d

from nlp.io.quality import true_runs

__all__ = ["NoiseModel", "noise_model", "sigma_ln", "welch_averages", "var_ln_welch",
           "var_ln_transient", "kernel_moment", "smoothing_taps", "estimator_kernel",
           "resolution_bias", "rest_mask",
           "rest_noise_psd", "local_scatter", "spaced_scatter", "correlation_lag",
           "second_difference_factor", "describe", "VAR_LN_MAX"]

# ln|z| of a complex Gaussian z has variance pi^2/24 (pure noise: no signal left)
VAR_LN_MAX = math.pi ** 2 / 24
_FLOOR = 1e-4      # sigma floor (numerical resolution of a stored FRF)
# share of the squared resolution bias kept as the leakage variance of an FRF file
# without coherence whose model carries the window's kernel (noise_model)
LEAKAGE_KEEP = 0.4


@dataclass(frozen=True)
class NoiseModel:
    """Standard deviations of one FRF set, on its full frequency grid.

    Attributes
    ----------
    sigma_ln : ndarray, shape (n_ch, n_f)
        Standard deviation of ln|H| [-].
    sigma_phase : ndarray, shape (n_ch, n_f)
        Standard deviation of arg H [rad].
    route : str
        ``"transient"``, ``"welch"``, ``"frf_coherence"`` or ``"scatter"``.
    n_averages : float
        Effective number of independent averages (1 for one segment).
    sigma_detect : ndarray, shape (n_ch, n_f), optional
        What decides whether something stands out of the noise (peaks, the whole-band
        map): ``sigma_ln`` plus the estimate's resolution bias when the model carries
        the window's kernel instead (:func:`estimator_kernel`). The bias, taken from
        second differences of the estimate, is also large where the estimate is
        noise, which keeps noise bumps out of the peaks. None: ``sigma_ln``.
    """

    sigma_ln: np.ndarray
    sigma_phase: np.ndarray
    route: str
    n_averages: float = 1.0
    sigma_detect: np.ndarray = None

    @property
    def detect(self):
        """Standard deviation of ln|H| for detection (see ``sigma_detect``)."""
        return self.sigma_ln if self.sigma_detect is None else self.sigma_detect


# ---------------------------------------------------------------- averaging
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


def smoothing_taps(window, nperseg=1024):
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
    leakage scatter that its scatter level cannot see (:func:`noise_model`). Windows
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
        nperseg = d.nperseg or int(2 ** np.floor(np.log2(max(records.t.size // 8, 1))))
    else:   # the file's segment length is not stated; the taps converge with it
        nperseg = 1024
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
    from scipy.special import exp1

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
    # part of bin 1; smoothed over 5 bins that read 20-45 % low below 2.5 bins (blind
    # 500199/60, white noise at fs 100 Hz: 0.76-0.86 of the mid-band level at 1.6 Hz,
    # where its first mode sat with a chi-square of 2); hold bin 2's level below it
    p[:, :2] = p[:, 2:3]
    kern = np.ones(5) / 5
    p = np.array([np.convolve(np.pad(pc, 2, mode="edge"), kern, mode="valid") for pc in p])
    return np.array([np.interp(f, fw, pc) for pc in p])


# ------------------------------------------------------------- local scatter
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
    from scipy.signal import get_window
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
    return _robust_levels(d2, H.shape[1], 1, half_width, second_difference_factor(window))


def _ln_unwrapped(H):
    """ln H with the phase unwrapped along frequency (zeros read as 1e-300)."""
    with np.errstate(divide="ignore"):
        lnH = np.log(np.where(H == 0, 1e-300, H))
    return lnH.real + 1j * np.unwrap(lnH.imag, axis=1)


def _robust_levels(d, n, shift, half_width, factor):
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
        out.append(np.maximum(s, _FLOOR))
    return out[0], out[1]


def correlation_lag(window=None, tol=1e-3):
    """Smallest bin lag beyond which a ``window``'s spectral estimate has uncorrelated
    bins: 1 + the largest l with |c_l| > tol (c_l as in :func:`second_difference_factor`).
    1 for independent bins (None, ``"none"``, ``"boxcar"``); 3 for Hann and Hamming
    (w^2 holds cosines up to 2 x the fundamental)."""
    if window is None or window in ("none", "boxcar"):
        return 1
    from scipy.signal import get_window
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
    bias added as in :func:`noise_model`, was 0.55-1.14 with :func:`local_scatter`
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
    return _robust_levels(d3, n, span // 2, half_width, float(np.sum(g ** 2)))


# ------------------------------------------------------------------ routes
def _from_records(case):
    """Transient (one segment) or Welch route for a case made from time histories."""
    d, rec = case.config.data, case.records
    names = [c.name for c in case.channels]
    x = rec.data["__input__"]
    y = np.array([rec.data[nm] for nm in names])
    n = rec.t.size
    nperseg = n if d.nperseg == "all" else d.nperseg
    if nperseg is None:
        nperseg = int(2 ** np.floor(np.log2(max(n // 8, 1))))
    noverlap = 0 if d.nperseg == "all" else int(d.overlap * nperseg)
    # segments of one record, and the overlap correction of their count
    n_d, n_eff = welch_averages(n, nperseg, noverlap, d.window)
    n_total = int(getattr(case, "n_averages", None) or n_d)   # all records (the estimator's)
    mask = rest_mask(x, y, rec.fs)
    s_n = None if mask is None else rest_noise_psd(np.vstack([x, y]), rec.fs, mask, case.f)
    if n_total == 1:
        if s_n is None:
            s, sp = local_scatter(case.f, case.H, window=d.window)
            return NoiseModel(s, sp, "scatter", 1.0)
        kw = dict(fs=rec.fs, window=d.window, nperseg=n, noverlap=0, detrend="constant")
        _, p_xx = signal.welch(x, **kw)
        _, p_yy = signal.welch(y, axis=-1, **kw)
        # the signal-to-noise ratio from periodograms averaged over 5 bins: a single
        # periodogram scatters like the noise itself where the response is weak, and a
        # noise bin that happens to be loud read as signal, with sigma 0.25 on a residual
        # of 2 (blind 500199/60 near its fmax: reduced chi-square 14 on an LVDT channel)
        kern = np.ones(5) / 5
        p_xx, p_yy = (np.apply_along_axis(lambda v: np.convolve(np.pad(v, 2, mode="edge"), kern,
                                                                 mode="valid"), -1, p)
                      for p in (p_xx, p_yy))
        var = var_ln_transient(p_xx, p_yy, s_n[0], s_n[1:])
        s = np.maximum(np.sqrt(var), _FLOOR)
        return NoiseModel(s, s.copy(), "transient", 1.0)
    n_eff = n_total * n_eff / n_d
    var = var_ln_welch(case.coherence, n_eff)
    # the resolution bias at sharp peaks is an error of the estimate as well, unless the
    # model sees it (Target.kernel); a whole transient per segment has no leakage
    bias2 = 0.0 if d.nperseg == "all" else \
        resolution_bias(case.H, kernel_moment(d.window, nperseg)) ** 2
    extra, cap = 0.0, np.inf
    if s_n is not None and d.estimator == "H1":
        # H1 is biased low by ln(1 + S_nx / S_uu) (input noise); count it as error
        kw = dict(fs=rec.fs, window=d.window, nperseg=nperseg, noverlap=noverlap)
        f_w, s_xx = signal.welch(x, **kw)
        s_xx = np.interp(case.f, f_w, s_xx)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.clip(s_n[0] / np.maximum(s_xx - s_n[0], 1e-300), 0, None)
        extra, cap = np.log1p(ratio)[None, :] ** 2, VAR_LN_MAX

    def sigma(v):
        return np.maximum(np.sqrt(np.minimum(v + extra, cap)), _FLOOR)

    s_det = sigma(var + bias2)
    if not getattr(case, "kernel", None):
        return NoiseModel(s_det, s_det.copy(), "welch", n_eff)
    s = sigma(var)
    return NoiseModel(s, s.copy(), "welch", n_eff, sigma_detect=s_det)


def noise_model(case):
    """The noise model of an assembled case (:func:`nlp.case.assemble.assemble`), by route.

    Returns
    -------
    NoiseModel
        On the case's full frequency grid ``case.f`` and channels.
    """
    if case.records is not None and "__input__" in case.records.data:
        return _from_records(case)
    # a stored FRF is (almost always) an analyzer's average with a window (data.window,
    # default Hann) at the file's own resolution: its peaks carry that window's resolution
    # bias, which no scatter or coherence shows; counted as error on a uniform grid
    bias2 = _file_resolution_bias2(case.f, case.H, case.config.data.window)
    if case.coherence is not None:
        n_eff = float(getattr(case, "n_averages", None) or 1.0)   # as the file states
        w = case.config.data.window
        if n_eff > 1 and w != "none":
            # an analyzer's averages overlap (data.overlap, default half): correlated
            # segments, as in the Welch route (welch_averages)
            step = max(int(round(1024 * (1.0 - case.config.data.overlap))), 1)
            n_eff = welch_averages(1024 + (int(n_eff) - 1) * step, 1024, 1024 - step, w)[1]
        if n_eff > 1:
            var = var_ln_welch(case.coherence, n_eff)
            s_det = np.maximum(np.sqrt(np.minimum(var + bias2, VAR_LN_MAX)), _FLOOR)
            if not getattr(case, "kernel", None):
                return NoiseModel(s_det, s_det.copy(), "frf_coherence", n_eff)
            # the model carries the window's kernel, so the bias is not an error of the fit
            s = np.maximum(np.sqrt(np.minimum(var, VAR_LN_MAX)), _FLOOR)
            return NoiseModel(s, s.copy(), "frf_coherence", n_eff, sigma_detect=s_det)
    s, sp = spaced_scatter(case.f, case.H, window=case.config.data.window)
    if np.ndim(bias2):
        # the bias is read from second differences of the noisy estimate, which carry
        # (m2/2)^2 x second_difference_factor x s^2 of the noise itself: counted once
        # already in s (blind null FRF files without coherence fitted at 0.67-0.84)
        w = case.config.data.window
        m2 = kernel_moment(w, 1024)
        bias2 = np.clip(bias2 - (0.5 * m2) ** 2 * second_difference_factor(w) * s ** 2, 0.0, None)
        # read bin by bin from a noisy estimate, the bias of a sharp peak lands on one bin
        # and misses its neighbour (blind 832173/62, a 1.1 % mode on 5 bins per bandwidth:
        # 0.005 estimated where the error was 0.078 on every channel alike, so the fit bent
        # to it and missed the shoulders by 11.6 x their noise): spread over +-1 bin.
        # Measured at the true FRF, z^2 at the fitted points of three blind null files:
        # 0.99, 1.03, 1.77 bin by bin; 0.73, 0.83, 0.98 spread (0.55-0.76 over +-2 bins)
        bias2 = uniform_filter1d(bias2, size=3, axis=-1, mode="nearest")
    if not getattr(case, "kernel", None):
        return NoiseModel(np.sqrt(s ** 2 + bias2), np.sqrt(sp ** 2 + bias2), "scatter", 1.0)
    # the model carries the window's kernel, so the bias itself is no error of the fit;
    # the leakage scatter at a sharp peak is, and the scatter level (over 51 bins) does
    # not see it. It scales with the same sharpness, so a share of bias^2 stands for it:
    # 0.4 brings z^2 at the peak bins of scipy-filtered Hann averages to 0.95 (1 % and
    # 2 % damping; tests/test_noise.py), where 0 gives 3.5 and 1 gives 0.53
    lk = LEAKAGE_KEEP * bias2
    return NoiseModel(np.sqrt(s ** 2 + lk), np.sqrt(sp ** 2 + lk), "scatter", 1.0,
                      sigma_detect=np.sqrt(s ** 2 + bias2))


# mean z^2 per file at the truth of 17 blind null FRF files without coherence (README,
# scripts/frf_file_noise_lead.py): what a level read from a file's own scatter is worth
SCATTER_RANGE = (0.7, 1.4)


def describe(model):
    """How the noise level was obtained, in words a user can weigh the chi-square by.

    Parameters
    ----------
    model : NoiseModel

    Returns
    -------
    dict
        ``route``, ``n_averages`` and ``statement``; ``measured`` is False when the level
        was read from the FRF's own scatter along frequency (no coherence, no rest
        portion), whose chi-square is then uncertain by about SCATTER_RANGE.
    """
    n = float(model.n_averages)
    text = {
        "transient": "one segment of a transient record; the variance of each point from the "
                     "noise measured in the record's rest portions (input and outputs)",
        "welch": f"Welch averages ({n:.1f} effective); the variance of each point from the "
                 "coherence",
        "frf_coherence": f"an FRF file with its coherence ({n:.1f} effective averages); the "
                         "variance of each point from the coherence",
        "scatter": "read from the FRF's own scatter along frequency (no coherence and no rest "
                   "portion to measure it from); against the truth, blind null files of this "
                   f"kind gave {SCATTER_RANGE[0]:g}-{SCATTER_RANGE[1]:g} in place of 1, so judge "
                   "the reduced chi-square to about that",
    }[model.route]
    return {"route": model.route, "n_averages": n, "measured": model.route != "scatter",
            "statement": "Noise: " + text + "."}


def _file_resolution_bias2(f, H, window="hann"):
    """Squared resolution bias of ln|H| of an FRF averaged with ``window`` on a uniform
    grid; 0 for ``window: none`` (an FRF not estimated by windowed averaging, e.g.
    stepped sine or a frequency-domain simulation) or a non-uniform grid."""
    f = np.asarray(f, float)
    if window == "none" or f.size < 5:
        return 0.0
    df = np.diff(f)
    if np.max(np.abs(df - df.mean())) > 1e-6 * abs(df.mean()):
        return 0.0
    return resolution_bias(H, kernel_moment(window, 1024)) ** 2


_LAST = [None, None]   # the last case and its model: diagnose asks several times per case


def sigma_ln(case, idx, model=None):
    """Standard deviation of ln|H| at points idx of every channel: (n_ch, len(idx)).

    model : a NoiseModel already computed for the case (else it is computed).
    """
    if model is None and getattr(case, "noise", None) is not None:
        model = case.noise
    if model is None:
        if _LAST[0] is not case:
            _LAST[:] = [case, noise_model(case)]
        model = _LAST[1]
    return model.sigma_ln[:, np.asarray(idx, int)]
