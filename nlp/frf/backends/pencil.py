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

The route is taken only when it is accurate: the first-order eigenvectors must be well
conditioned (1-norm condition times eps below ``TRUST``) and the solves must pass a
backward-error check at ``CHECKS`` frequencies. Otherwise :func:`decompose` returns None
and the caller factorises at each frequency, as before.
"""

import numpy as np
import scipy.linalg as sla

__all__ = ["decompose", "Pencil", "TRUST", "BACKWARD"]

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
        X = self.L @ Y.reshape(p, n_rhs * N)               # one matrix product for all
        return X.reshape(-1, n_rhs, N).transpose(1, 0, 2)

    def backward_error(self, w, rhs, X):
        """Largest relative backward error of the solves X (n_rhs, n, N) at frequencies w."""
        A0, A1, A2 = self.mats
        worst = 0.0
        for k, wk in enumerate(np.asarray(w, float)):
            Z = A0 + 1j * wk * A1 - wk ** 2 * A2
            Xk = X[:, :, k].T
            res = np.linalg.norm(Z @ Xk - rhs)
            scale = np.linalg.norm(Z) * np.linalg.norm(Xk) + np.linalg.norm(rhs)
            worst = max(worst, res / scale)
        return worst


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
    w_check = np.asarray(w_check, float)
    picks = w_check[np.unique(np.linspace(0, w_check.size - 1, CHECKS).astype(int))]
    if not p.backward_error(picks, rhs_check, p.solve(picks, rhs_check)) <= BACKWARD:
        return None
    return p


def _asym(A):
    return np.linalg.norm(A - A.T) / max(np.linalg.norm(A), np.finfo(float).tiny)
