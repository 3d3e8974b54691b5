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
               resolution (:func:`nlp.frf.kernel.estimator_kernel`), as for Welch.
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

import numpy as np
from scipy import signal
from scipy.ndimage import uniform_filter1d

from nlp.frf.estimate import default_nperseg
from nlp.frf.kernel import (FILE_NPERSEG, file_resolution_bias2, kernel_moment, resolution_bias,
                            welch_averages)
from nlp.frf.scatter import local_scatter, second_difference_factor, spaced_scatter
from nlp.frf.variance import (SIGMA_FLOOR, VAR_LN_MAX, rest_mask, rest_noise_psd,
                              var_ln_transient, var_ln_welch)

__all__ = ["NoiseModel", "noise_model", "sigma_ln", "describe", "SCATTER_RANGE", "LEAKAGE_KEEP"]

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
        the window's kernel instead (:func:`nlp.frf.kernel.estimator_kernel`). The bias, taken from
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
        nperseg = default_nperseg(n)
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
        # of 2 (measured on a blind one-segment record near its fmax: reduced chi-square 14
        # on an LVDT channel; docs/benchmarks/history.md)
        kern = np.ones(5) / 5
        p_xx, p_yy = (np.apply_along_axis(lambda v: np.convolve(np.pad(v, 2, mode="edge"), kern,
                                                                 mode="valid"), -1, p)
                      for p in (p_xx, p_yy))
        var = var_ln_transient(p_xx, p_yy, s_n[0], s_n[1:])
        s = np.maximum(np.sqrt(var), SIGMA_FLOOR)
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
        return np.maximum(np.sqrt(np.minimum(v + extra, cap)), SIGMA_FLOOR)

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
    bias2 = file_resolution_bias2(case.f, case.H, case.config.data.window)
    if case.coherence is not None:
        n_eff = float(getattr(case, "n_averages", None) or 1.0)   # as the file states
        w = case.config.data.window
        if n_eff > 1 and w != "none":
            # an analyzer's averages overlap (data.overlap, default half): correlated
            # segments, as in the Welch route (welch_averages)
            L = FILE_NPERSEG
            step = max(int(round(L * (1.0 - case.config.data.overlap))), 1)
            n_eff = welch_averages(L + (int(n_eff) - 1) * step, L, L - step, w)[1]
        if n_eff > 1:
            var = var_ln_welch(case.coherence, n_eff)
            s_det = np.maximum(np.sqrt(np.minimum(var + bias2, VAR_LN_MAX)), SIGMA_FLOOR)
            if not getattr(case, "kernel", None):
                return NoiseModel(s_det, s_det.copy(), "frf_coherence", n_eff)
            # the model carries the window's kernel, so the bias is not an error of the fit
            s = np.maximum(np.sqrt(np.minimum(var, VAR_LN_MAX)), SIGMA_FLOOR)
            return NoiseModel(s, s.copy(), "frf_coherence", n_eff, sigma_detect=s_det)
    s, sp = spaced_scatter(case.f, case.H, window=case.config.data.window)
    if np.ndim(bias2):
        # the bias is read from second differences of the noisy estimate, which carry
        # (m2/2)^2 x second_difference_factor x s^2 of the noise itself: counted once
        # already in s (blind null FRF files without coherence fitted at 0.67-0.84)
        w = case.config.data.window
        m2 = kernel_moment(w, FILE_NPERSEG)
        bias2 = np.clip(bias2 - (0.5 * m2) ** 2 * second_difference_factor(w) * s ** 2, 0.0, None)
        # read bin by bin from a noisy estimate, the bias of a sharp peak lands on one bin
        # and misses its neighbour (measured on a blind FRF file, a 1.1 % mode on 5 bins per
        # bandwidth, docs/benchmarks/history.md:
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
