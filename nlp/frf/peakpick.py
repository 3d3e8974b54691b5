"""Modes of the measured FRFs by peak picking, and their comparison with a model.

For each resonance peak (found as in :func:`nlp.frf.freqsel.find_peaks`): the
natural frequency is the peak's frequency, the damping ratio comes from the
half-power bandwidth, zeta = (f_hi - f_lo) / (2 f_r), and the mode shape is
the imaginary part of the channels' FRFs at the peak, in receptance form
(absolute accelerance minus 1, divided by (jw)^p): quadrature picking. At a
lightly damped resonance the resonant mode's term is in quadrature while the
other modes' terms are nearly real, so the imaginary part isolates the mode
even when the input barely excites it; its MAC with the model's mode at the
same DOFs measures shape agreement.
"""

import numpy as np

from nlp.frf.forms import POWER
from nlp.frf.freqsel import find_peaks, half_power_band, peak_curve
from nlp.frf.reference import BASE_DOF, modal_parameters
from nlp.frf.metrics import mac, modal_errors

__all__ = ["pick_modes", "compare_modes"]


def _receptance_form(f, H, channels):
    jw = 2j * np.pi * f
    out = np.empty_like(H)
    for c, ch in enumerate(channels):
        h = H[c] - 1.0 if ch.output == "absolute_accelerance" else H[c]
        out[c] = h / np.where(jw == 0, 1, jw) ** POWER[ch.output]
    return out


def pick_modes(f, H, channels, detection=None, fmin=None, fmax=None, sigma=None):
    """Frequencies [Hz], damping ratios and shapes (n_ch, n_modes) of the peaks.

    detection : the FRFs in which to look for peaks (default H), e.g. the
    accelerance form used for frequency selection; sigma : std of ln|detection|
    (n_ch, n_f), the noise a peak must stand out of (`freqsel.find_peaks`).
    """
    D = H if detection is None else detection
    shapes = _receptance_form(f, H, channels)
    fr, zr, phi = [], [], []
    for ip in find_peaks(f, D, fmin=fmin, fmax=fmax, sigma=sigma):
        curve = peak_curve(f, D, ip)
        lo, hi = half_power_band(f, curve, ip)
        win = slice(max(ip - 2, 0), ip + 3)
        i = win.start + int(np.argmax(curve[win]))
        fr.append(f[i])
        zr.append((hi - lo) / (2 * f[i]) if np.isfinite(lo) and np.isfinite(hi) else np.nan)
        phi.append(shapes[:, i].imag)  # quadrature picking
    return np.array(fr), np.array(zr), np.array(phi).T.reshape(len(channels), len(fr))


def compare_modes(M, C, K, f, H, channels, detection=None, fmin=None, fmax=None, phase=True,
                  sigma=None):
    """Peak-picked modes against the model's: one dict per measured mode.

    ``phase=False`` (magnitude-only data): frequency and damping only; the
    MAC needs the quadrature part of the FRFs, so it is None. sigma : as in
    `pick_modes`.
    """
    f_x, z_x, phi_x = pick_modes(f, H, channels, detection, fmin, fmax, sigma)
    if f_x.size == 0:
        return []
    f_a, z_a, Phi = modal_parameters(M, C, K)
    ferr, _, pair = modal_errors(f_a, z_a, f_x, np.nan_to_num(z_x))
    dofs = [ch.dof for ch in channels]
    Phi = np.array([Phi[d] if d != BASE_DOF else np.zeros(Phi.shape[1]) for d in dofs])
    dofs = list(range(len(dofs)))
    rows = []
    for k in range(f_x.size):
        j = int(pair[k])
        m = None if not phase else \
            float(mac(Phi[dofs, j], phi_x[:, k])[0, 0]) if j >= 0 else float("nan")
        rows.append({"f_measured_hz": float(f_x[k]), "zeta_measured": float(z_x[k]),
                     "f_model_hz": float(f_a[j]) if j >= 0 else None,
                     "zeta_model": float(z_a[j]) if j >= 0 else None,
                     "frequency_error": float(ferr[k]), "mac": m})
    return rows
