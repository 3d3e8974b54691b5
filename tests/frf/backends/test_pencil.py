"""Solves by one eigendecomposition (nlp.frf.backends.pencil) against direct LU solves."""

import numpy as np
import pytest

from nlp.frf.backends.pencil import decompose, span, update


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


def _with_appendage(K, M, C, at, ms, ks, cs, mass_at=None, dm=0.0):
    """K, M, C bordered by an appendage (ms, ks, cs) hanging from DOF ``at``, and a lumped
    mass dm at ``mass_at``: the augmented model written out entry by entry."""
    n = K.shape[0]
    Ka, Ma, Ca = (np.pad(A, (0, 1)) for A in (K, M, C))
    for A, v in ((Ka, ks), (Ca, cs)):
        A[at, at] += v
        A[n, n] += v
        A[at, n] -= v
        A[n, at] -= v
    Ma[n, n] = ms
    if mass_at is not None:
        Ma[mass_at, mass_at] += dm
    return Ka, Ma, Ca


def test_low_rank_update_equals_lu_solves_of_the_augmented_model():
    """An appendage with its own dashpot and an added mass on a Rayleigh frame (damping not
    proportional): the base's modal sum plus the Woodbury update against LU solves."""
    rng = np.random.default_rng(7)
    n = 10
    K, M = _shear(n, rng)
    C = 0.3 * M + 2e-3 * K
    Ka, Ma, Ca = _with_appendage(K, M, C, at=6, ms=40.0, ks=40.0 * (2 * np.pi * 3.0) ** 2,
                                 cs=2 * 0.05 * 40.0 * 2 * np.pi * 3.0, mass_at=2, dm=150.0)
    # base: the frame alone, the extra DOF given a stiff, heavy, proportional stand-in
    Kb, Mb, Cb = (np.pad(A, (0, 1)) for A in (K, M, C))
    Kb[n, n], Mb[n, n] = 4 * K.max(), M.mean()
    Cb[n, n] = 0.3 * Mb[n, n] + 2e-3 * Kb[n, n]
    w = _band(K, M)
    rhs = np.column_stack([Ma @ np.r_[np.ones(n), 1.0], np.eye(n + 1)[:, [0, 6, n]]])
    base = decompose(Kb, Cb, Mb, w, rhs)
    assert base is not None and base.d is not None          # the base is a modal sum
    Q = span([Ka - Kb, Ca - Cb, Ma - Mb])
    assert Q.shape[1] == 3                                   # the appendage, its DOF, the mass
    p = update(base, Q, (Ka, Ca, Ma), w, rhs)
    assert p is not None
    ref = _direct(Ka, Ca, Ma, w, rhs).transpose(1, 0, 2)
    assert np.max(np.abs(p.solve(w, rhs) - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_update_refuses_a_change_outside_its_span():
    rng = np.random.default_rng(2)
    n = 6
    K, M = _shear(n, rng)
    C = 0.3 * M + 2e-3 * K
    w = _band(K, M)
    rhs = np.eye(n)[:, :2]
    base = decompose(K, C, M, w, rhs)
    M2 = M.copy()
    M2[1, 1] += 200.0
    M2[4, 4] += 200.0
    Q = np.eye(n)[:, [1]]                                    # misses the change at DOF 4
    assert update(base, Q, (K, C, M2), w, rhs) is None
    assert update(base, np.eye(n)[:, [1, 4]], (K, C, M2), w, rhs) is not None
