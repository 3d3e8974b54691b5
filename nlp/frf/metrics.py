"""Comparison metrics between analytical (or simulated) and measured data.

All functions are pure and take arrays. FRF arrays are shaped
(n_channels, n_freq); a 1-D array is one channel. Subscript ``a`` is the
analytical/updated model, ``x`` the experiment.
"""

import numpy as np
from scipy.optimize import linear_sum_assignment

from nlp.errors import InputError

__all__ = ["fdac", "fdac_overall", "frac", "mac", "nrmse", "correlation", "peak_error",
           "modal_errors"]

_SRC = "<arguments>"


def _pair2d(H_a, H_x):
    """Both FRF sets as 2-D arrays of one shape."""
    H_a = np.atleast_2d(np.asarray(H_a))
    H_x = np.atleast_2d(np.asarray(H_x))
    if H_a.shape != H_x.shape or H_a.ndim != 2:
        raise InputError(_SRC, "H_a", f"the same (n_channels, n_freq) shape as H_x {H_x.shape}",
                         got=f"shape {H_a.shape}")
    return H_a, H_x


def _assurance(a, x):
    """|a^H x|^2 / ((a^H a)(x^H x)) along the last axis; 0/0 gives NaN."""
    num = np.abs(np.sum(np.conj(x) * a, axis=-1)) ** 2
    den = np.sum(np.abs(a) ** 2, axis=-1) * np.sum(np.abs(x) ** 2, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return num / den


def fdac(H_a, H_x):
    """Frequency domain assurance criterion per channel, on magnitudes.

    ``FDAC = (|H_a|.|H_x|)^2 / ((|H_a|.|H_a|)(|H_x|.|H_x|))`` over the given
    frequency points (Pascual et al. 1997, as used for the paper's Figure 6).
    1 means the magnitude curves have the same shape (any scale), 0 none.

    Parameters
    ----------
    H_a, H_x : array_like, shape (n_ch, n_f) or (n_f,)
        Analytical and experimental FRFs at the same frequency points.

    Returns
    -------
    ndarray, shape (n_ch,)
    """
    H_a, H_x = _pair2d(H_a, H_x)
    return _assurance(np.abs(H_a), np.abs(H_x))


def fdac_overall(H_a, H_x):
    """FDAC over all channels' points concatenated (one number).

    Equals ``fdac`` on the long vector of the paper's Eqn 22.
    """
    H_a, H_x = _pair2d(H_a, H_x)
    return float(_assurance(np.abs(H_a).ravel(), np.abs(H_x).ravel()))


def frac(H_a, H_x):
    """Complex frequency response assurance criterion per channel.

    ``FRAC = |sum conj(H_x) H_a|^2 / (sum |H_x|^2 sum |H_a|^2)``; unlike FDAC
    it also sees phase differences.

    Returns
    -------
    ndarray, shape (n_ch,)
    """
    H_a, H_x = _pair2d(H_a, H_x)
    return _assurance(H_a, H_x)


def mac(phi_a, phi_x):
    """Modal assurance criterion matrix for complex mode shapes.

    Parameters
    ----------
    phi_a : array_like, shape (n_dof, n_a)
        Mode shapes as columns.
    phi_x : array_like, shape (n_dof, n_x)

    Returns
    -------
    ndarray, shape (n_a, n_x)
        ``MAC[i, j] = |phi_a_i^H phi_x_j|^2 / ((phi_a_i^H phi_a_i)(phi_x_j^H phi_x_j))``.
    """
    pa = np.asarray(phi_a)
    px = np.asarray(phi_x)
    pa = pa[:, None] if pa.ndim == 1 else pa
    px = px[:, None] if px.ndim == 1 else px
    if pa.ndim != 2 or px.ndim != 2 or pa.shape[0] != px.shape[0]:
        raise InputError(_SRC, "phi_a", f"columns of the same length as phi_x's ({px.shape[0]})",
                         got=f"shape {pa.shape}")
    cross = np.abs(pa.conj().T @ px) ** 2
    na = np.sum(np.abs(pa) ** 2, axis=0)
    nx = np.sum(np.abs(px) ** 2, axis=0)
    return cross / np.outer(na, nx)


def _same_shape(sim, meas):
    sim = np.asarray(sim)
    meas = np.asarray(meas)
    if sim.shape != meas.shape:
        raise InputError(_SRC, "sim", f"the same shape as meas {meas.shape}",
                         got=f"shape {sim.shape}")
    return sim, meas


def _rms(z):
    return np.sqrt(np.mean(np.abs(z) ** 2, axis=-1))


def nrmse(sim, meas):
    """Normalised RMS error ``rms(sim - meas) / rms(meas)`` along the last axis."""
    sim, meas = _same_shape(sim, meas)
    return _rms(sim - meas) / _rms(meas)


def correlation(sim, meas):
    """Pearson correlation coefficient along the last axis (real signals)."""
    sim, meas = _same_shape(sim, meas)
    ds = sim - sim.mean(axis=-1, keepdims=True)
    dm = meas - meas.mean(axis=-1, keepdims=True)
    return np.sum(ds * dm, axis=-1) / np.sqrt(np.sum(ds ** 2, axis=-1) * np.sum(dm ** 2, axis=-1))


def peak_error(sim, meas):
    """Relative peak error ``(max|sim| - max|meas|) / max|meas|`` along the last axis."""
    sim, meas = _same_shape(sim, meas)
    pm = np.max(np.abs(meas), axis=-1)
    return (np.max(np.abs(sim), axis=-1) - pm) / pm


def modal_errors(f_a, zeta_a, f_x, zeta_x):
    """Natural-frequency and damping errors after pairing modes by frequency.

    Each experimental mode is paired with an analytical mode, one to one,
    minimising the total relative frequency distance ``|f_a - f_x| / f_x``
    (Hungarian algorithm); with well-separated modes this is the nearest mode.

    Parameters
    ----------
    f_a, zeta_a : array_like, shape (n_a,)
        Analytical natural frequencies [Hz] and damping ratios [-].
    f_x, zeta_x : array_like, shape (n_x,)
        Experimental natural frequencies [Hz] and damping ratios [-].

    Returns
    -------
    freq_error : ndarray, shape (n_x,)
        Relative frequency error ``(f_a - f_x) / f_x`` [-].
    damping_error : ndarray, shape (n_x,)
        Damping-ratio difference ``zeta_a - zeta_x`` (absolute, not relative;
        signed) [-].
    pair : ndarray of int, shape (n_x,)
        Index of the paired analytical mode; -1 (and NaN errors) when there
        are fewer analytical than experimental modes.
    """
    f_a, zeta_a, f_x, zeta_x = (np.atleast_1d(np.asarray(v, dtype=float))
                                for v in (f_a, zeta_a, f_x, zeta_x))
    if f_a.shape != zeta_a.shape or f_x.shape != zeta_x.shape:
        raise InputError(_SRC, "zeta", "one damping ratio per natural frequency")
    if np.any(f_x <= 0):
        raise InputError(_SRC, "f_x", "positive frequencies in Hz", got=f_x)
    cost = np.abs(f_a[None, :] - f_x[:, None]) / f_x[:, None]
    rows, cols = linear_sum_assignment(cost)
    pair = np.full(f_x.size, -1)
    pair[rows] = cols
    ok = pair >= 0
    freq_error = np.full(f_x.size, np.nan)
    damping_error = np.full(f_x.size, np.nan)
    freq_error[ok] = (f_a[pair[ok]] - f_x[ok]) / f_x[ok]
    damping_error[ok] = zeta_a[pair[ok]] - zeta_x[ok]
    return freq_error, damping_error, pair
