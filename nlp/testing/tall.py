"""Tall shear frames with one parameter per storey: data by an independent modal sum.

The "measured" FRFs come from the eigen-decomposition of the lumped-mass shear chain
(``scipy.linalg.eigh_tridiagonal`` of M^-1/2 K M^-1/2) and a sum over all modes, exact
for Rayleigh damping, which is diagonal in the undamped modes; the package's FRF code is
not used. Ground (shake-table) input, relative-displacement receptances at 4 floors,
40 n points from 0.5 f1 to 1.1 fn, multiplicative complex noise.

The nominal model the updater starts from has every mass 5 % off and every stiffness
10 % off the truth (signs drawn per storey); floor 1 is weighed, so it is fixed at its
true mass and anchors the M-C-K scale (DEVELOPERS.md fact 1): 2 n + 1 free parameters
(n stiffnesses, n - 1 masses, the 2 Rayleigh coefficients).
"""

import numpy as np
import scipy.linalg as sla

__all__ = ["TallFrame", "tall_frame", "modal_receptance", "case_dict"]

ZETA = 0.02          # Rayleigh damping ratio at modes 1 and n
NOISE = 0.005        # relative complex noise (0.5 %)
POINTS_PER_STOREY = 40
MASS_OFF, STIFF_OFF = 0.05, 0.10


class TallFrame:
    """Truth, nominal model and simulated data of one tall frame (attributes, SI units)."""

    def __init__(self, n, m, k, a0, a1, m_nom, k_nom, f, H, dofs, noise):
        self.n, self.m, self.k, self.a0, self.a1 = n, m, k, a0, a1
        self.m_nom, self.k_nom, self.f, self.H, self.dofs, self.noise = m_nom, k_nom, f, H, dofs, noise


def modal_receptance(m, k, omega, dofs, a0, a1):
    """Relative-displacement receptance [m/(m/s^2)] of floors ``dofs`` (0-based) per unit
    ground acceleration, by modal superposition over all n undamped modes."""
    diag = (k + np.append(k[1:], 0.0)) / m
    off = -k[1:] / np.sqrt(m[:-1] * m[1:])
    lam, V = sla.eigh_tridiagonal(diag, off)
    wr = np.sqrt(lam)
    Phi = V / np.sqrt(m)[:, None]              # mass-normalised
    gamma = Phi.T @ (-m)                       # phi_r^T b with b = -M 1
    out = np.empty((len(dofs), omega.size), complex)
    for s in range(0, omega.size, 512):        # memory flat in n x N
        w = omega[s:s + 512]
        den = wr[:, None] ** 2 - w[None, :] ** 2 + 1j * w[None, :] * (a0 + a1 * wr[:, None] ** 2)
        out[:, s:s + 512] = (Phi[dofs] * gamma) @ (1.0 / den)
    return out, wr


def tall_frame(n, seed=0, noise=NOISE, points_per_storey=POINTS_PER_STOREY, sensors=4):
    """An n-storey frame (masses 1000 kg, stiffness tapering 2e6 -> 1e6 N/m up the height
    with +-5 % scatter), its nominal model and noisy receptances at ``sensors`` floors
    spread evenly from floor 1 to the roof."""
    rng = np.random.default_rng([seed, n])
    m = 1000.0 * (1 + rng.uniform(-0.05, 0.05, n))
    k = 2.0e6 * np.linspace(1.0, 0.5, n) * (1 + rng.uniform(-0.05, 0.05, n))
    lam = sla.eigh_tridiagonal((k + np.append(k[1:], 0)) / m, -k[1:] / np.sqrt(m[:-1] * m[1:]),
                               eigvals_only=True)
    w1, wn = np.sqrt(lam[0]), np.sqrt(lam[-1])
    a0, a1 = 2 * ZETA * w1 * wn / (w1 + wn), 2 * ZETA / (w1 + wn)
    f = np.linspace(0.5 * w1, 1.1 * wn, points_per_storey * n) / (2 * np.pi)
    dofs = sorted(set(np.linspace(0, n - 1, sensors).round().astype(int).tolist()))
    H, _ = modal_receptance(m, k, 2 * np.pi * f, dofs, a0, a1)
    e = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    H = H * (1 + noise * e)
    m_nom = m * (1 + MASS_OFF * rng.choice([-1.0, 1.0], n))
    m_nom[0] = m[0]                            # floor 1 weighed
    k_nom = k * (1 + STIFF_OFF * rng.choice([-1.0, 1.0], n))
    return TallFrame(n, m, k, a0, a1, m_nom, k_nom, f, H, dofs, noise)


def case_dict(frame, data_file="frf.npz", frequencies=None, weighed="first"):
    """The case YAML (as a dict) of a tall frame: per-storey stiffnesses free, Rayleigh
    damping from 2 % at modes 1 and n; floor 1 weighed (``weighed="first"``, the other
    masses free) or every floor weighed (``"all"``, masses fixed at the truth)."""
    n = frame.n
    floors = range(n) if weighed == "all" else range(1)
    return {
        "name": f"tall_shear_frame_{n}",
        "description": f"{n}-storey shear frame, per-storey parameters, independent modal-sum data",
        "model": {"type": "shear_frame", "masses": [round(float(v), 3) for v in frame.m_nom],
                  "stiffnesses": [round(float(v), 1) for v in frame.k_nom]},
        "parameters": {"stiffness_bounds": [-0.5, 1.0], "mass_bounds": [-0.5, 1.0],
                       "fixed": {f"m{i + 1}": round(float(frame.m[i]), 3) for i in floors}},
        "damping": {"model": "rayleigh", "zeta": ZETA},
        "excitation": {"type": "ground"},
        "data": {"file": data_file, "window": "none",
                 "channels": [{"name": f"floor{d + 1}", "floor": d + 1, "output": "receptance",
                               "column": i} for i, d in enumerate(frame.dofs)]},
        "frequencies": {"method": "all"} if frequencies is None else frequencies,
        "objective": {"residual": "log_magnitude"},
        "solver": {"name": "ipopt", "options": {"max_iter": 500}},
        "search": {"starts": 4, "seed": 0, "workers": 1},
    }
