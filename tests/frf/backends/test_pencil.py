"""Solves by one eigendecomposition (nlp.frf.backends.pencil) against direct LU solves."""

import numpy as np
import pytest

from nlp.frf.backends.pencil import decompose


def _shear(n, rng):
    k = rng.uniform(1e5, 3e5, n)
    K = np.diag(k + np.r_[k[1:], 0.0]) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    M = np.diag(rng.uniform(800, 1200, n))
    return K, M


def _direct(A0, A1, A2, w, rhs):
    return np.stack([np.linalg.solve(A0 + 1j * wk * A1 - wk ** 2 * A2, rhs) for wk in w], axis=-1)


def _band(K, M, n_pts=300):
    lam = np.linalg.eigvals(np.linalg.solve(M, K)).real
    return np.linspace(0.3 * np.sqrt(lam.min()), 1.3 * np.sqrt(lam.max()), n_pts)


@pytest.mark.parametrize("kind", ["rayleigh", "general", "hysteretic_group", "complex_general"])
def test_pencil_solves_equal_lu_solves(kind):
    rng = np.random.default_rng(4)
    n = 8
    K, M = _shear(n, rng)
    A0, A2 = K.astype(complex), M
    if kind == "rayleigh":
        A1 = 0.3 * M + 2e-3 * K
    else:
        L = rng.standard_normal((n, n)) * 40.0
        A1 = L @ L.T                      # general SPD damping: not proportional
    if kind == "hysteretic_group":
        P = np.zeros((n, n))
        P[2:4, 2:4] = [[1.0, -1.0], [-1.0, 1.0]]
        A0 = K + 1j * 0.05 * 2e5 * P      # loss on one story only: not proportional
        A1 = 0.3 * M + 2e-3 * K
    if kind == "complex_general":
        A0 = K * (1 + 0.02j)
    w = _band(K, M)
    rhs = np.column_stack([M @ np.ones(n), np.eye(n)[:, [0, 3, n - 1]]])
    p = decompose(A0, A1, A2, w, rhs)
    assert p is not None
    assert (p.d is not None) == (kind == "rayleigh")   # proportional damping: modal sum
    X = p.solve(w, rhs)                                 # (n_rhs, n, N)
    ref = _direct(A0, A1, A2, w, rhs).transpose(1, 0, 2)
    assert np.max(np.abs(X - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_pencil_refuses_singular_or_nonsymmetric_mass():
    rng = np.random.default_rng(1)
    K, M = _shear(5, rng)
    w = _band(K, M)
    rhs = np.eye(5)[:, :2]
    M0 = M.copy()
    M0[4, 4] = 0.0                         # a massless DOF: no first-order form
    assert decompose(K, 0.01 * K, M0, w, rhs) is None
    Mn = M.copy()
    Mn[0, 1] = 5.0                         # not symmetric
    assert decompose(K, 0.01 * K, Mn, w, rhs) is None


def test_pencil_refuses_defective_damping():
    # one DOF at critical damping: a double eigenvalue with a single eigenvector
    K, M = np.array([[4.0]]), np.array([[1.0]])
    C = np.array([[4.0]])                  # c = 2 sqrt(k m)
    A1 = np.block([[C, np.zeros((1, 1))], [np.zeros((1, 1)), np.array([[0.1]])]])
    A0 = np.block([[K, np.zeros((1, 1))], [np.zeros((1, 1)), np.array([[9.0]])]])
    A0[0, 1] = A0[1, 0] = 1e-3             # coupled: the damping is not proportional
    A2 = np.eye(2)
    w = np.linspace(0.1, 5.0, 50)
    rhs = np.eye(2)
    p = decompose(A0, A1, A2, w, rhs)
    if p is not None:                      # if accepted, it must be accurate
        ref = _direct(A0, A1, A2, w, rhs).transpose(1, 0, 2)
        assert np.max(np.abs(p.solve(w, rhs) - ref)) <= 1e-7 * np.max(np.abs(ref))
