"""Peak picking recovers the modes of an exactly known system."""

import numpy as np
from scipy import linalg

from nlp.frf.peakpick import compare_modes, pick_modes
from nlp.solve.problem import Channel


def _system():
    m = np.array([2.0, 1.5, 1.0])
    k = np.array([1000.0, 750.0, 500.0])
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    lam, Phi = linalg.eigh(K, M)
    zeta = np.array([0.01, 0.015, 0.008])
    C = M @ Phi @ np.diag(2 * zeta * np.sqrt(lam)) @ Phi.T @ M
    return M, C, K, np.sqrt(lam) / (2 * np.pi), zeta, Phi


def test_peak_picking_on_exact_accelerances():
    M, C, K, fn, zeta, Phi = _system()
    f = np.arange(0.05, 10.0, 0.002)
    w = 2 * np.pi * f
    H = np.array([-(wk**2) * np.linalg.solve(K - wk**2 * M + 1j * wk * C, [0, 0, 1.0]) for wk in w]).T
    chans = [Channel(f"a{i}", i, "accelerance") for i in range(3)]
    f_x, z_x, phi = pick_modes(f, H, chans)
    np.testing.assert_allclose(f_x, fn, atol=0.004)
    np.testing.assert_allclose(z_x, zeta, rtol=0.05)
    for j in range(3):
        c = abs(phi[:, j] @ Phi[:, j]) ** 2 / ((phi[:, j] @ phi[:, j]) * (Phi[:, j] @ Phi[:, j]))
        assert c > 0.99
    rows = compare_modes(M, C, K, f, H, chans)
    assert len(rows) == 3 and all(r["mac"] > 0.99 and abs(r["frequency_error"]) < 1e-3 for r in rows)
