"""Planting by frequency-based substructuring (nlp/testing/plant.py) against direct
solves of the modified model, and gain / delay against their time-domain meaning."""

import numpy as np
import pytest

from nlp.testing.plant import (added_mass_z, appendage_z, attach, attach_accelerance,
                               attach_transfer, delay, gain, receptance)

W = 2 * np.pi * np.linspace(0.5, 60.0, 2000)      # rad/s, across and beyond the three modes


def _frame():
    """A 3-DOF shear frame with non-proportional damping: M [kg], K [N/m], C [N s/m]."""
    m = np.array([5.4, 4.6, 4.7])
    k = np.array([38000.0, 44000.0, 39000.0])
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1], 0.0], [-k[1], k[1] + k[2], -k[2]], [0.0, -k[2], k[2]]])
    C = 0.3 * M + 2e-5 * K
    C[0, 0] += 4.0                                 # a dashpot to the ground: not proportional
    return M, K, C


def _column(M, K, C, p):
    """Receptance column R_{:,p} [m/N] by a direct solve of (K - w^2 M + j w C) x = e_p."""
    e = np.zeros(M.shape[0])
    e[p] = 1.0
    return np.array([np.linalg.solve(K - w**2 * M + 1j * w * C, e) for w in W]).T


def _rel(a, b):
    return np.max(np.abs(a - b) / np.abs(b))


@pytest.mark.parametrize("p", [0, 1, 2])
def test_added_mass_matches_the_direct_solve(p):
    M, K, C = _frame()
    dm = 1.7
    M2 = M.copy()
    M2[p, p] += dm
    planted = attach(_column(M, K, C, p), p, added_mass_z(W, dm))
    assert _rel(planted, _column(M2, K, C, p)) < 1e-10


@pytest.mark.parametrize("p", [0, 1, 2])
def test_appendage_matches_the_augmented_model(p):
    M, K, C = _frame()
    m_a, f_a, zeta = 0.6, 17.0, 0.02
    k_a = m_a * (2 * np.pi * f_a) ** 2
    c_a = 2 * zeta * m_a * 2 * np.pi * f_a
    n = M.shape[0]
    Ma, Ka, Ca = (np.zeros((n + 1, n + 1)) for _ in range(3))
    Ma[:n, :n], Ka[:n, :n], Ca[:n, :n] = M, K, C
    Ma[n, n] = m_a
    for A, v in ((Ka, k_a), (Ca, c_a)):            # spring and dashpot between p and the new DOF
        A[p, p] += v
        A[n, n] += v
        A[p, n] -= v
        A[n, p] -= v
    direct = _column(Ma, Ka, Ca, p)[:n]
    z = appendage_z(W, m_a, k_a, c_a)
    planted = attach(_column(M, K, C, p), p, z)
    assert _rel(planted, direct) < 1e-10
    # away from the driving point: input at b, the appendage at p
    b = (p + 1) % n
    R_b, R_p = _column(M, K, C, b), _column(M, K, C, p)
    transfer = attach_transfer(R_b, R_p, R_b[p], R_p[p], z)
    assert _rel(transfer, _column(Ma, Ka, Ca, b)[:n]) < 1e-10
    assert _rel(transfer, R_b) > 1e-3


def test_accelerance_route_matches_the_direct_solve():
    M, K, C = _frame()
    p, dm = 1, 2.0
    M2 = M.copy()
    M2[p, p] += dm
    A = -W**2 * _column(M, K, C, p)
    planted = attach_accelerance(A, W, p, added_mass_z(W, dm))
    assert _rel(receptance(planted, W), _column(M2, K, C, p)) < 1e-10


def test_a_stiff_appendage_is_a_rigid_mass():
    z = appendage_z(W, 0.8, 1e16, 0.0)
    assert _rel(z, added_mass_z(W, 0.8)) < 1e-6


def _amplitude(t, y, w):
    """Complex amplitude H of y(t) = Re(H exp(j w t)) by least squares."""
    B = np.column_stack([np.cos(w * t), -np.sin(w * t)])
    (re, im), *_ = np.linalg.lstsq(B, y, rcond=None)
    return re + 1j * im


def test_delay_and_gain_are_what_a_delayed_scaled_signal_shows():
    """A sensor that reports g y(t - tau) of the response y(t) = Re(H exp(j w t))."""
    H, tau, g = 0.3 - 1.2j, 3.7e-3, 1.11
    t = np.linspace(0.0, 2.0, 4001)
    for w in (2 * np.pi * 6.5, 2 * np.pi * 26.5):
        y_seen = g * np.real(H * np.exp(1j * w * (t - tau)))
        assert abs(_amplitude(t, y_seen, w) - gain(delay(H, w, tau), g)) < 1e-10
    assert delay(H, 0.0, tau) == H
    assert np.allclose(gain(np.array([H, 2 * H]), 0.9), [0.9 * H, 1.8 * H], rtol=0, atol=1e-15)
