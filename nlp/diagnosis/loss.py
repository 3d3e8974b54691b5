"""Hysteretic (frequency-independent) loss from magnitude and phase together.

A general viscous C has n(n+1)/2 free entries, enough to give every mode the
damping it shows at its resonance, so a log-magnitude fit reproduces a
hysteretic loss K_h = eta K (or eta K_s on one story) mode by mode and never
needs it: off resonance the two differ in |H| only to second order in the
damping. They differ to first order in the phase. Below a mode of frequency
f_r, a viscous dashpot tuned to the same modal damping lags by
eta (f / f_r) / (1 - (f / f_r)^2), a hysteretic loss by eta / (1 - (f / f_r)^2):
the difference eta / (1 + f / f_r) is most of eta over the whole band below the
mode, and it has the same sign on every channel.

So the final model of a log-magnitude diagnosis is refitted once more with the
complex residual (magnitude and phase) over the coherently measured band off
the resonances' half-power windows, with and without a loss at each location (the whole frame, each story). A loss is
reported when the best location meets the evidence rules of :mod:`.evidence`
(scaled BIC drop of at least BIC_ACCEPT, eta more than LOSS_Z quasi standard
errors from zero) and explains a real part of the phase misfit. Locations within
BIC_TIE of the best are reported as not told apart.

This module holds the decision on the refits; :func:`nlp.diagnosis.driver._loss_check`
builds and solves them.
"""

import numpy as np

from nlp.diagnosis.evidence import BIC_ACCEPT, BIC_TIE, SIGNIFICANCE, scaled_delta_bic

__all__ = ["MAX_POINTS", "MAX_SIGMA", "LOSS_Z", "EXPLAINED", "band_points", "loss_row",
           "loss_decision"]

MAX_POINTS = 1200      # points of the band refitted (evenly thinned): enough for the phase
MAX_SIGMA = 0.3        # [rad] points with a noisier phase are not used (wrapping, noise floor)
LOSS_Z = 2 * SIGNIFICANCE   # eta this many quasi standard errors from 0: the location is
                            # chosen among n + 1 after the forward selection, as for delays
EXPLAINED = 0.2        # fraction of the complex misfit above the noise the loss must remove


def band_points(f, mask, sigma_phase, fmax=None, exclude=(), max_points=MAX_POINTS):
    """Indices of the frequencies every channel measured coherently with a usable phase,
    off the resonances.

    At a resonance the fitted viscous C already gives the mode the loss's damping, so the
    two forms agree there; what the points near a peak do carry is the estimate's own
    bias (the smoothing by an FRF file's unknown window, leakage). On a null H1 file
    without coherence they made a small whole-frame loss stand out at 6.6 standard errors;
    without them none stands out, while the losses of 0.01-0.07 are found as before
    (see docs/method/diagnosis.md).

    Parameters
    ----------
    f : ndarray, shape (n_f,)
        Frequencies [Hz].
    mask : ndarray of bool, shape (n_ch, n_f) or (1, n_f)
        Coherently measured points (:func:`.band.band_mask`).
    sigma_phase : ndarray, shape (n_ch, n_f)
        Standard deviation of the measured phase [rad].
    fmax : float, optional
        Top of the band [Hz].
    exclude : array of int
        Indices left out: the fitted half-power windows of the resonances.
    max_points : int
        At most this many points, evenly thinned.

    Returns
    -------
    ndarray of int
    """
    ok = np.all(mask, axis=0) & (f > 0) & np.all(sigma_phase < MAX_SIGMA, axis=0)
    if fmax is not None:
        ok &= f <= fmax
    ok[np.asarray(exclude, int)] = False
    idx = np.nonzero(ok)[0]
    if idx.size > max_points:
        idx = idx[:: int(np.ceil(idx.size / max_points))]
    return idx


def loss_row(location, eta, se, chi2, chi2_null, n_points, k_total, converged):
    """Evidence of one location's loss refit against the refit without a loss.

    chi2, chi2_null are complex-residual chi-squares (residuals over noise) on
    n_points residuals (two per point and channel); k_total the refit's free
    parameters. The dispersion phi is that of the refit with the loss.
    """
    dof = max(n_points - k_total, 1)
    phi = max(1.0, chi2 / dof)
    drop = chi2_null - chi2
    return {"location": location, "eta": float(eta), "standard_error": float(se),
            "chi2": float(chi2), "chi2_null": float(chi2_null), "phi": phi,
            "delta_bic": scaled_delta_bic(chi2, chi2_null, 1, n_points, phi),
            # share of the misfit above the noise (chi2_null - dof) that the loss removes
            "explained": drop / max(chi2_null - dof, drop, 1e-12),
            "converged": bool(converged)}


def _significant(r):
    return (r["converged"] and r["delta_bic"] <= -BIC_ACCEPT
            and r["eta"] > LOSS_Z * r["standard_error"] and r["standard_error"] < r["eta"]
            and r["explained"] >= EXPLAINED)


def loss_decision(rows):
    """The best significant location and the others it cannot be told apart from.

    Parameters
    ----------
    rows : list of dict
        :func:`loss_row` per location (``location``: {} for the whole frame, or
        {"between": [s - 1, s]}).

    Returns
    -------
    (best, tied) : (dict or None, list of dict)
        best is None when no location is significant; tied are the other
        significant locations within BIC_TIE of the best.
    """
    for r in rows:
        r["significant"] = _significant(r)
    sig = sorted((r for r in rows if r["significant"]), key=lambda r: r["delta_bic"])
    if not sig:
        return None, []
    best = sig[0]
    return best, [r for r in sig[1:] if r["delta_bic"] - best["delta_bic"] < BIC_TIE]
