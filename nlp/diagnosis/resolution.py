"""Can the data resolve an appendage from a reshaped peak?

An appendage (secondary oscillator) is a separate resonance only when the mode it
adds and the structural mode nearest to it are further apart than their
half-power bandwidths (2 zeta f) and than the resolution of the FRF estimate.
Closer, the two merge into one peak whose shape the general damping, the
estimator's window and the noise can also explain: a tiny oscillator tuned onto
a mode then fits the window's smoothing of that peak, not physics (blind case
886679/57, an ordinary change: mass ratio 0.0004 tuned 0.1 % below mode 2 of a
Welch estimate whose peaks are 1.3-6 bins wide). A real appendage of detectable
size (mass ratio >= 0.025 within +-25 % of a mode) splits far wider, by about
f sqrt(mu) where it is tuned onto the mode.
"""

import numpy as np
from scipy import signal

from ..frf import modal_parameters

__all__ = ["estimate_resolution", "appendage_split"]


def estimate_resolution(f, window):
    """Resolution of an FRF estimate [Hz]: bin spacing times the window's equivalent
    noise bandwidth in bins (Hann 1.5, rectangular 1).

    f : frequency grid [Hz]; window : the estimate's window name ("hann", "boxcar",
    "none" for an FRF not estimated by windowed averaging).
    """
    f = np.asarray(f, float)
    df = float(np.median(np.diff(f))) if f.size > 1 else 0.0
    if not window or window in ("none", "boxcar", "rectangular"):
        return df
    w = signal.get_window(window, 1024)
    return df * 1024 * float(w @ w) / float(w.sum()) ** 2


def appendage_split(M, K, C, dof=-1):
    """The appendage's mode and the structural mode nearest to it.

    M, K, C : the whole system [kg, N/m, N s/m] with the appendage's DOF at ``dof``.
    The appendage's mode is the one with the largest share of kinetic energy in that
    DOF. Returns (separation [Hz], max half-power bandwidth 2 zeta f of the two [Hz],
    appendage-mode frequency [Hz], nearest-mode frequency [Hz]).
    """
    fn, zeta, Phi = modal_parameters(M, C, K)
    m = np.real(np.diag(M))
    energy = m[:, None] * np.abs(Phi) ** 2
    share = energy[dof] / np.maximum(energy.sum(axis=0), 1e-300)
    a = int(np.argmax(share))
    others = [j for j in range(fn.size) if j != a]
    if not others:
        return np.inf, 0.0, float(fn[a]), np.nan
    b = min(others, key=lambda j: abs(fn[j] - fn[a]))
    bw = max(2 * zeta[a] * fn[a], 2 * zeta[b] * fn[b])
    return float(abs(fn[a] - fn[b])), float(bw), float(fn[a]), float(fn[b])
