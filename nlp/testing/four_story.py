"""The paper's four-story shear frame as a truth model, and its FRF data from a seed.

Truth: the masses and stiffnesses of Table 1's "Average of the updated" row and a
non-proportional damping matrix (Rayleigh plus two local dashpots). Data:
ground-acceleration receptance FRFs of all four floors on 0.02-12 Hz with 2 % complex
Gaussian noise (relative to |H| at each point).

The FRFs come from the package's `frf_dynamic_stiffness` and the damping from its
`rayleigh_from_ratios`: these data check fitting, not those functions (the tests of
`nlp.frf.reference` use closed forms).
"""

import numpy as np

from nlp.frf.reference import frf_dynamic_stiffness, modal_parameters
from nlp.model.damping import rayleigh_from_ratios
from nlp.model.nominal import shear_stiffness

MASSES = np.array([5.16, 5.15, 4.94, 5.14])                # kg, Table 1 average row
STIFFNESSES = np.array([1054.98, 1284.19, 1377.13, 2738.17])  # N/m, Table 1 average row


def true_damping(M, K):
    """Rayleigh (1.5 % at modes 1 and 4) plus dashpots ground-floor 1 and floors 3-4."""
    a0, a1 = rayleigh_from_ratios(M, K, 0.015)
    C = a0 * M + a1 * K
    C[0, 0] += 0.8                      # ground to floor 1 [N s/m]
    c34 = 0.4                           # floor 3 to floor 4
    C[2, 2] += c34
    C[3, 3] += c34
    C[2, 3] -= c34
    C[3, 2] -= c34
    return C


def make(seed=0, noise=0.02, f=None):
    """Return (f, H_noisy, truth dict)."""
    f = np.arange(0.02, 12.0 + 1e-9, 0.02) if f is None else f
    M = np.diag(MASSES)
    K = shear_stiffness(STIFFNESSES)
    C = true_damping(M, K)
    H = frf_dynamic_stiffness(M, C, K, 2 * np.pi * f, excitation="ground", output="receptance")
    rng = np.random.default_rng(seed)
    e = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    Hn = H * (1 + noise * e)
    fn, zeta, _ = modal_parameters(M, C, K)
    truth = {"masses": MASSES.tolist(), "stiffnesses": STIFFNESSES.tolist(), "C": C.tolist(),
             "natural_frequencies_hz": fn.tolist(), "damping_ratios": zeta.tolist(),
             "seed": seed, "noise": noise}
    return f, Hn, truth
