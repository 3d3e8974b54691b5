"""Complex symmetric banded solves at many frequencies at once, without pivoting, checked.

Z_k = K - w_k^2 M + j w_k C (Eqns 2-5) is complex symmetric and, after reverse
Cuthill-McKee ordering, banded with half-bandwidth b. Gaussian elimination without
pivoting of a symmetric matrix is Z = L D L^T, and every frequency runs the same
operations, so one pass over the n columns factorises all N_c frequencies of a chunk
with numpy operations along the frequency axis (the last, contiguous one): about
n (4 b^2 + 6 b + 6) real flops per frequency for the factors and n (16 b + 6) per
right-hand side, with n Python steps per chunk instead of one LAPACK call per frequency.

Why no pivoting is safe: -jZ = wC - j(K - w^2 M) has the Hermitian part wC, positive
definite for w > 0 and C > 0. Elimination without pivoting keeps that property in every
Schur complement, so no pivot vanishes. That does not bound the growth of the factors when
the damping is light, and a search's trial points may have C indefinite, so every
frequency is CHECKED. The computed solution of each right-hand side satisfies
(Z + dZ) x = b with |dZ| <= gamma |L||D||L^T|, gamma ~ 3 (b + 1) u (Higham, Accuracy and
Stability of Numerical Algorithms, 2nd ed., Thm 9.4: the bound needs only the terms of
each banded inner product), so

    ||Z x - b|| <= gamma G ||Z|| ||x||,   G = || |L||D||L^T| || / ||Z||   (infinity norms)

for all n_rhs solves at once. G costs O(b n) per frequency, less than one solve; the
frequencies with G > ``GROWTH_MAX`` (or not finite: a vanishing pivot) are solved again by LAPACK's pivoted banded solver. Pivoted LU itself guarantees a bound of
the same form with its own growth factor.
"""

import numpy as np
import scipy.linalg as sla

__all__ = ["GROWTH_MAX", "lower_band", "ldlt_banded", "ldlt_solve", "growth", "row_norm",
           "solve_pivoted", "solve_banded_batch"]

# G is 18-22 on tall shear frames (n = 32-256, nominal and perturbed parameters: K - w^2 M
# cancels on the diagonal above the first mode). G <= 1e3 bounds the backward error of every
# solve by about 1e-11 for b <= 3 and 1e-10 for b = 40; a vanishing pivot gives G = inf or nan.
GROWTH_MAX = 1e3


def lower_band(zvals, index, b, n):
    """The lower band storage L[p, j, k] = Z_k[j + p, j], p = 0..b (complex, (b+1, n, N_c)).

    ``index`` holds, for each lower-triangle pattern entry, its flat position p * n + j in
    the (b+1, n) storage, and ``zvals`` (entries, N_c) their values at each frequency.
    """
    L = np.zeros(((b + 1) * n, zvals.shape[1]), complex)
    L[index] = zvals
    return L.reshape(b + 1, n, -1)


def ldlt_banded(L):
    """Factorise Z = L D L^T at every frequency (no pivoting), overwriting L.

    On return L[0] holds 1/D and L[1:] the subdiagonals of the unit lower factor.
    """
    b, n = L.shape[0] - 1, L.shape[1]
    if b == 1:
        return _ldlt_tridiagonal(L)
    for j in range(n):
        inv = np.divide(1.0, L[0, j], out=L[0, j])
        h = min(b, n - 1 - j)
        if h:
            col = L[1:h + 1, j]                   # Z[j + p, j], p = 1..h (columns > j change)
            lj = col * inv
            for p in range(1, h + 1):             # Z[j+q, j+p] -= l_q d l_p for q >= p
                L[0:h - p + 1, j + p] -= lj[p - 1:h] * col[p - 1]
            col[...] = lj
    return L


def _ldlt_tridiagonal(L):
    """:func:`ldlt_banded` for b = 1, the same operations in the same order, written into
    preallocated rows: each of a shear frame's n steps is five array operations without
    temporaries."""
    d, e = L[0], L[1]
    lj, upd = np.empty_like(d[0]), np.empty_like(d[0])
    for j in range(L.shape[1] - 1):
        np.divide(1.0, d[j], out=d[j])              # 1 / D_j
        np.multiply(e[j], d[j], out=lj)             # l_j = Z[j+1, j] / D_j
        d[j + 1] -= np.multiply(lj, e[j], out=upd)  # Z[j+1, j+1] -= l_j Z[j+1, j]
        e[j] = lj
    np.divide(1.0, d[-1], out=d[-1])
    return L


def ldlt_solve(F, X):
    """Solve L D L^T x = rhs in place for X (n, n_rhs, N_c), F from :func:`ldlt_banded`."""
    b, n = F.shape[0] - 1, F.shape[1]
    tmp = np.empty(X.shape[1:], complex)
    if b == 1:                                    # the same steps, without the band logic
        e = F[1]
        for j in range(n - 1):
            X[j + 1] -= np.multiply(e[j], X[j], out=tmp)
        X *= F[0][:, None]
        for j in range(n - 2, -1, -1):
            X[j] -= np.multiply(e[j], X[j + 1], out=tmp)
        return X
    for j in range(n - 1):                        # L y = rhs
        h = min(b, n - 1 - j)
        if h == 1:                                # no temporaries in the tridiagonal case
            X[j + 1] -= np.multiply(F[1, j], X[j], out=tmp)
        else:
            X[j + 1:j + h + 1] -= F[1:h + 1, j, None] * X[j]
    X *= F[0][:, None]                            # D z = y
    for j in range(n - 2, -1, -1):                # L^T x = z
        h = min(b, n - 1 - j)
        if h == 1:
            X[j] -= np.multiply(F[1, j], X[j + 1], out=tmp)
        else:
            X[j] -= (F[1:h + 1, j, None] * X[j + 1:j + h + 1]).sum(axis=0)
    return X


def growth(F, znorm):
    """|| |L| |D| |L^T| ||_inf / ||Z||_inf at every frequency, F from :func:`ldlt_banded`.

    Row i of |L||D||L^T| sums to sum_k |L_ik| |D_k| sum_j |L_jk|, a banded product.
    """
    b, n = F.shape[0] - 1, F.shape[1]
    absL = np.abs(F[1:])
    s = (1.0 + absL.sum(axis=0)) / np.abs(F[0])   # |D_k| sum_j |L_jk|
    rows = s.copy()
    for p in range(1, b + 1):                      # L[i, i - p] = F[p, i - p]
        rows[p:] += absL[p - 1, :n - p] * s[:n - p]
    return rows.max(axis=0) / znorm


def row_norm(L):
    """||Z||_inf at every frequency for the symmetric band L (b+1, n, N_c)."""
    b, n = L.shape[0] - 1, L.shape[1]
    A = np.abs(L)
    rows = A[0].copy()
    for p in range(1, b + 1):
        rows[p:] += A[p, :n - p]
        rows[:n - p] += A[p, :n - p]
    return rows.max(axis=0)


def solve_pivoted(Lk, rhs):
    """LAPACK's pivoted banded solve (the fallback) for one frequency's band Lk (b+1, n);
    rhs (n, n_rhs) -> (n, n_rhs)."""
    b, n = Lk.shape[0] - 1, Lk.shape[1]
    ab = np.zeros((2 * b + 1, n), complex)
    for p in range(b + 1):                        # ab[b + i - j, j] = Z[i, j]
        ab[b + p, :n - p] = Lk[p, :n - p]
        ab[b - p, p:] = Lk[p, :n - p]
    return sla.solve_banded((b, b), ab, rhs, check_finite=False)


def solve_banded_batch(L, rhs, growth_max=None):
    """Solve Z_k x = rhs for every frequency k of the band L (b+1, n, N_c); rhs (n, n_rhs).

    L is overwritten by the factors. Returns X (n, n_rhs, N_c) and the indices of the
    frequencies that need the pivoted fallback (:func:`solve_pivoted`): their growth G
    exceeded ``growth_max`` (default ``GROWTH_MAX``).
    """
    growth_max = GROWTH_MAX if growth_max is None else growth_max
    znorm = row_norm(L)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        F = ldlt_banded(L)
        bad = np.nonzero(~(growth(F, znorm) <= growth_max))[0]
        X = np.empty(rhs.shape + L.shape[2:], complex)
        X[...] = rhs[:, :, None]
        ldlt_solve(F, X)
    return X, bad
