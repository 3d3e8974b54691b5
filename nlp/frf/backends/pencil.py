"""Solves of a small dense system at many frequencies from one eigendecomposition.

Z(w) = A0 + j w A1 - w^2 A2, with A2 = M symmetric positive definite and Re A0 = K
symmetric. The undamped modes Phi (K Phi = M Phi Lambda, Phi^T M Phi = I) turn it into

    Z(w) = Phi^-T (A0~ + j w A1~ - w^2 I) Phi^-1,   A0~ = Phi^T A0 Phi, A1~ = Phi^T A1 Phi.

- Proportional damping (A0~ and A1~ diagonal, e.g. Rayleigh, or a global loss factor):
  every solve is the modal sum Phi diag(1 / (a0_i + j w a1_i - w^2)) Phi^T r.
- Otherwise the first-order form of Eqn 4 in modal coordinates, y = [x~; s x~] with
  s = j w, is diagonalised by its eigenvectors V (Eqn 5):
  Z(s)^-1 r = Phi V_top diag(1 / (s - lambda)) (V^-1)[:, n:] Phi^T r (Eqns 15, 17).

One eigendecomposition per evaluation (n^3 flops for the modes, about 25 (2n)^3 for the
first-order form) then replaces N LU factorisations (8/3 n^3 each), and each frequency
costs a matrix product: on the 2,100-DOF frame's reduced system (n = 109, N = 795,
Rayleigh damping) 0.01 Gflop in place of 3 Gflop.

A few local additions (an appendage, an added mass: the families' terms) make the damping
non-proportional, and the first-order form then costs 10-20 times the modal sum. When the
additions span a few directions Q (rank r << n), Z = Z_b + Q D(w) Q^T with Z_b proportional:
:func:`update` solves by the base's modal sum plus an r x r system per frequency (the
Woodbury identity in its push-through form, which needs no inverse of D).

The route is taken only when it is accurate: the first-order eigenvectors must be well
conditioned (1-norm condition times eps below ``TRUST``) and the solves must pass a
backward-error check at ``CHECKS`` frequencies. Otherwise :func:`decompose` returns None
and the caller factorises at each frequency, as before.
"""

import numpy as np
import scipy.linalg as sla

from nlp.frf.backends.bilinear import real_times_complex

__all__ = ["decompose", "update", "span", "stand_in", "on_pattern", "Pencil", "Updated", "TRUST",
           "BACKWARD"]

TRUST = 1e-8       # largest cond_1(V) * eps accepted: the solves keep about 8 digits
BACKWARD = 1e-10   # largest ||Z x - r||_F / (||Z||_F ||x||_F + ||r||_F) at the check points
CHECKS = 5         # frequencies at which the backward error is checked
DIAGONAL = 1e-12   # off-diagonal share of A0~, A1~ below which damping is proportional


class Pencil:
    """Z(w)^-1 r = L diag(g(w)) R r for one evaluation's Z: g = 1 / (a0 + j w a1 - w^2)
    (proportional damping) or 1 / (j w - lambda) (first-order form)."""

    def __init__(self, L, R, mats, d=None, lam=None):
        self.L, self.R, self.mats = L, R, mats
        self.d, self.lam = d, lam

    def gains(self, w):
        """g (n_poles, N) at circular frequencies w [rad/s]."""
        w = np.asarray(w, float)[None, :]
        if self.d is not None:
            a0, a1 = self.d
            return 1.0 / (a0[:, None] + 1j * w * a1[:, None] - w ** 2)
        return 1.0 / (1j * w - self.lam[:, None])

    def solve(self, w, rhs):
        """X (n_rhs, n, N) with Z(w_k) X[:, :, k].T = rhs, for circular frequencies w (N,)."""
        C = self.R @ rhs                                   # (poles, n_rhs) participations
        Y = C[:, :, None] * self.gains(w)[:, None, :]      # (poles, n_rhs, N)
        p, n_rhs, N = Y.shape
        Y = Y.reshape(p, n_rhs * N)
        # one matrix product for all; real modes (proportional damping) in real arithmetic
        X = self.L @ Y if np.iscomplexobj(self.L) else real_times_complex(self.L, Y)
        return X.reshape(-1, n_rhs, N).transpose(1, 0, 2)

    def backward_error(self, w, rhs, X):
        """Largest relative backward error of the solves X (n_rhs, n, N) at frequencies w."""
        return _backward_error(self.mats, w, rhs, X)


class Updated:
    """Z(w)^-1 r for Z = Z_b(w) + Q D(w) Q^T, D(w) = D0 + j w D1 - w^2 D2 (r x r):

        Z^-1 r = G r - G Q (I + D Q^T G Q)^-1 D Q^T G r,   G = Z_b^-1 (the base's pencil).
    """

    def __init__(self, base, Q, D, mats):
        self.base, self.Q, self.D, self.mats = base, Q, D, mats

    def solve(self, w, rhs):
        """X (n_rhs, n, N) with Z(w_k) X[:, :, k].T = rhs, for circular frequencies w (N,)."""
        w = np.asarray(w, float)
        n_rhs, r = rhs.shape[1], self.Q.shape[1]
        X = self.base.solve(w, np.column_stack([rhs, self.Q]))   # G [rhs, Q]
        Gr, GQ = X[:n_rhs], X[n_rhs:]
        QGQ = np.tensordot(self.Q.T, GQ, axes=([1], [1])).transpose(2, 0, 1)   # (N, r, r)
        QGr = np.tensordot(self.Q.T, Gr, axes=([1], [1])).transpose(2, 0, 1)   # (N, r, n_rhs)
        D0, D1, D2 = self.D
        Dk = D0[None] + 1j * w[:, None, None] * D1[None] - (w ** 2)[:, None, None] * D2[None]
        Y = np.linalg.solve(np.eye(r)[None] + Dk @ QGQ, Dk @ QGr)           # (N, r, n_rhs)
        return Gr - np.einsum("ank,kai->ink", GQ, Y)

    def backward_error(self, w, rhs, X):
        """Largest relative backward error of the solves X (n_rhs, n, N) at frequencies w."""
        return _backward_error(self.mats, w, rhs, X)


def _backward_error(mats, w, rhs, X):
    A0, A1, A2 = mats
    worst = 0.0
    for k, wk in enumerate(np.asarray(w, float)):
        Z = A0 + 1j * wk * A1 - wk ** 2 * A2
        Xk = X[:, :, k].T
        res = np.linalg.norm(Z @ Xk - rhs)
        scale = np.linalg.norm(Z) * np.linalg.norm(Xk) + np.linalg.norm(rhs)
        worst = max(worst, res / scale)
    return worst


def _accurate(p, w_check, rhs_check):
    """p if its solves pass the backward-error test at ``CHECKS`` frequencies, else None."""
    w_check = np.asarray(w_check, float)
    picks = w_check[np.unique(np.linspace(0, w_check.size - 1, CHECKS).astype(int))]
    if not p.backward_error(picks, rhs_check, p.solve(picks, rhs_check)) <= BACKWARD:
        return None
    return p


def _offdiag_share(A):
    d = np.diag(A)
    return np.linalg.norm(A - np.diag(d)) / max(np.linalg.norm(d), np.finfo(float).tiny)


def _first_order(a0, a1):
    """Eigenvalues and V_top, (V^-1)[:, n:] of [[0, I], [-a0, -a1]] (modal coordinates),
    or None when V is ill conditioned."""
    n = a0.shape[0]
    comp = np.zeros((2 * n, 2 * n), np.result_type(a0, a1))
    comp[:n, n:] = np.eye(n)
    comp[n:, :n] = -a0
    comp[n:, n:] = -a1
    lam, V = np.linalg.eig(comp)   # real input: LAPACK's real routine, pairs of conjugates
    try:
        V_inv = np.linalg.inv(V)
    except np.linalg.LinAlgError:
        return None
    cond = np.linalg.norm(V, 1) * np.linalg.norm(V_inv, 1)
    if not np.isfinite(cond) or cond * np.finfo(float).eps > TRUST:
        return None
    return lam, V[:n], V_inv[:, n:]


def decompose(A0, A1, A2, w_check, rhs_check):
    """The :class:`Pencil` of Z(w) = A0 + j w A1 - w^2 A2 (dense n x n), or None.

    None when A2 is not symmetric positive definite, Re A0 not symmetric, the
    first-order eigenvectors ill conditioned (``TRUST``), or the solves at ``CHECKS``
    frequencies spread over ``w_check`` [rad/s] with right-hand sides ``rhs_check``
    (n, n_rhs) fail the backward-error test (``BACKWARD``).
    """
    K, M = np.real(A0), np.real(A2)
    if np.iscomplexobj(A2) and np.any(np.imag(A2)):
        return None
    sym = np.finfo(float).eps * 1e3
    if _asym(K) > sym or _asym(M) > sym:
        return None
    try:
        _, Phi = sla.eigh(0.5 * (K + K.T), 0.5 * (M + M.T), check_finite=False)
    except (np.linalg.LinAlgError, ValueError):
        return None
    a0, a1 = Phi.T @ A0 @ Phi, Phi.T @ A1 @ Phi
    if max(_offdiag_share(a0), _offdiag_share(a1)) < DIAGONAL:
        p = Pencil(Phi, Phi.T, (A0, A1, A2), d=(np.diag(a0), np.diag(a1)))
    else:
        fo = _first_order(a0, a1)
        if fo is None:
            return None
        lam, V_top, W = fo
        p = Pencil(Phi @ V_top, W @ Phi.T, (A0, A1, A2), lam=lam)
    return _accurate(p, w_check, rhs_check)


def span(matrices, extra=0, tol=1e-12):
    """Orthonormal Q (n, r) spanning the columns of every (n, n) matrix, dense or sparse
    (each scaled to unit norm), and the last ``extra`` unit vectors: singular values above
    ``tol`` times the largest."""
    cols = []
    for A in matrices:
        A = A.toarray() if hasattr(A, "toarray") else np.asarray(A)
        a = np.linalg.norm(A)
        if a > 0:
            cols.append(A / a)
    if not cols:
        return None
    n = cols[0].shape[0]
    cols.append(np.eye(n)[:, n - extra:])
    U, s, _ = np.linalg.svd(np.hstack(cols), full_matrices=False)
    return U[:, s > tol * s[0]]


def on_pattern(n, rows, cols, values):
    """The dense (n, n) matrix with ``values`` at (rows, cols), zero elsewhere."""
    A = np.zeros((n, n), complex if np.iscomplexobj(values) else float)
    A[rows, cols] = values
    return A


def stand_in(A, extra, cK, cM):
    """A0, A1, A2 (Rayleigh damping A1 = cM A2 + cK Re A0) whose last ``extra`` DOFs, empty in
    them (the DOFs the families append), get the mean mass and 4 times the largest stiffness
    on the diagonal, damped by the same law: the base of :func:`update` stays definite and
    proportional, its stand-in modes above the model's (the backward-error test guards the
    rest)."""
    if not extra:
        return A
    A = [a.copy() for a in A]
    n = A[0].shape[0]
    e = np.arange(n - extra, n)
    m_ref = np.mean(np.diag(A[2])[:n - extra].real)
    k_ref = 4.0 * np.max(np.diag(A[0])[:n - extra].real)
    A[0][e, e] += k_ref
    A[1][e, e] += cK * k_ref + cM * m_ref
    A[2][e, e] += m_ref
    return A


def update(base, Q, mats, w_check, rhs_check):
    """The :class:`Updated` solves of Z = A0 + j w A1 - w^2 A2 (``mats``, dense n x n) from
    the pencil ``base`` of Z_b, where Z - Z_b lies in span Q; None when ``base`` is None or
    the solves fail the backward-error test (``BACKWARD``) at ``CHECKS`` frequencies."""
    if base is None:
        return None
    D = tuple(Q.T @ (A - B) @ Q for A, B in zip(mats, base.mats))
    return _accurate(Updated(base, Q, D, mats), w_check, rhs_check)


def _asym(A):
    return np.linalg.norm(A - A.T) / max(np.linalg.norm(A), np.finfo(float).tiny)
