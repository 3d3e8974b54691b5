"""Can the data resolve an appendage from a reshaped peak?

An appendage (secondary oscillator) is a separate resonance only when the mode it
adds and the structural mode nearest to it are further apart than the sum of
their half-power half-widths (zeta_a f_a + zeta_b f_b: their half-power bands do
not overlap) and than the resolution of the FRF estimate. Closer, the two merge
into one peak whose shape the general damping, the
estimator's window and the noise can also explain: a tiny oscillator tuned onto
a mode then fits the window's smoothing of that peak, not physics (on an ordinary
change without an appendage, a mass ratio of 0.0004 tuned 0.1 % below a mode of a
Welch estimate whose peaks are a few bins wide). A real appendage of detectable
size (mass ratio >= 0.025 within +-25 % of a mode) splits far wider, by about
f sqrt(mu) where it is tuned onto the mode.

The larger of the two full bandwidths (2 zeta f), used before, refused damped
appendages whose half-power bands stand apart (a true appendage with a dBIC in the
tens of thousands and a held-out misfit 27 times lower than the family named in its
place; see docs/method/diagnosis.md).
"""

import numpy as np
from scipy import signal

from nlp.frf.reference import modal_parameters

__all__ = ["estimate_resolution", "case_resolution", "appendage_split", "resolved", "damping_pinned"]


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


def case_resolution(case):
    """Resolution [Hz] of the case's FRF estimate (estimate_resolution of its grid and window)."""
    return estimate_resolution(case.f, case.config.data.window)


def appendage_split(M, K, C, dof=-1):
    """The appendage's mode and the structural mode nearest to it.

    M, K, C : the whole system [kg, N/m, N s/m] with the appendage's DOF at ``dof``.
    The appendage's mode is the one with the largest share of kinetic energy in that
    DOF. Returns (separation [Hz], sum of the two modes' half-power half-widths
    zeta_a f_a + zeta_b f_b [Hz], appendage-mode frequency [Hz], nearest-mode
    frequency [Hz]).
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
    half = zeta[a] * fn[a] + zeta[b] * fn[b]
    return float(abs(fn[a] - fn[b])), float(half), float(fn[a]), float(fn[b])


def resolved(separation, half_widths, resolution):
    """Two modes [Hz apart] are separate resonances in the data when their half-power
    bands do not overlap (separation > half_widths, from appendage_split) and the
    estimate resolves them (separation > resolution, from estimate_resolution)."""
    return bool(separation > max(half_widths, resolution))


def damping_pinned(zeta_s, se, lower):
    """The appendage's fitted damping ratio is determined (its standard error under its
    value) and lies within one standard error of the lower bound of its box: the data
    ask for a line at least as sharp as the model allows. Such a line fits an excursion
    of the estimate a bin or two wide, not a resonance (on the benchmark, the spurious
    appendages offered on cases without a resolvable one sat at the bound, while the
    true ones fitted damping ratios of 0.03-0.06, 3 to 37 errors above it; see
    docs/method/diagnosis.md). A damping the data leave open
    (error above its value) is a nuisance reported as not determined, and does not
    decide (nlp.diagnosis.evidence.undetermined).

    zeta_s, se : fitted damping ratio and its standard error; lower : the bound.
    """
    return bool(zeta_s - lower <= se < abs(zeta_s))
