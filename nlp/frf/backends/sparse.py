"""Exact FRF and its analytic sensitivities with one sparse factorisation per frequency.

For each frequency w_k the system of :mod:`nlp.frf.backends.system` is
factorised once (small systems: one batched dense LU over all frequencies;
else a banded LU after reverse Cuthill-McKee ordering when the band is
narrow, SuperLU on the same ordering without pivoting otherwise (a minimum-degree
ordering with pivoting for the bordered damping system); a rank-m
damping term U S U^T enters as a bordered system [[Z_s, jw U S], [U^T, -I]],
so C never fills Z in). The same factors give

    q = Z^-1 b                       (the FRF of every DOF, Eqns 2-5)
    lambda_c = Z^-1 e_c              (adjoint of channel c; Z is symmetric)
    dH_c / dtheta_i = lambda_c^T (db/dtheta_i - dZ/dtheta_i q)

and dZ/dtheta_i is a fixed sparse matrix times a scalar (M and K are linear
in alpha and beta, Eqns 23-24), so each sensitivity is a sparse bilinear form:
the cost is (1 + n_channels) solves per frequency whatever the number of
parameters. Runs in numpy/scipy and enters the CasADi NLP as callbacks.
"""

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla
import casadi as ca

from nlp.frf.forms import POWER

__all__ = ["SparseFRF", "BAND_MAX"]

BAND_MAX = 40  # half-bandwidth up to which the banded LU beats SuperLU (measured at n = 2000)
BATCH_MAX = 24  # up to this size one batched dense LU over all frequencies beats the banded LU (measured)


def _aggregate(mats, W, n):
    """Matrices sum_i W[i, j] A_i, one per column j of W (sparse)."""
    r, c, v, which = _triplets(mats)
    out = []
    for j in range(W.shape[1]):
        wv = W[which, j] * v if v.size else v
        keep = wv != 0
        out.append(sp.csc_matrix((wv[keep], (r[keep], c[keep])), shape=(n, n)))
    return out


def _triplets(mats):
    """(rows, cols, values, matrix index) of all nonzeros of a list of sparse matrices."""
    parts = []
    for i, A in enumerate(mats):
        A = A if sp.isspmatrix_csc(A) else sp.csc_matrix(A)
        cols = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
        parts.append((A.indices, cols, A.data, np.full(A.data.size, i)))
    if not parts:
        return (np.zeros(0, int),) * 2 + (np.zeros(0),) + (np.zeros(0, int),)
    return tuple(np.concatenate(x) for x in zip(*parts))


class _Pattern:
    """The union sparsity pattern of fixed matrices, and each one's values on it.

    ``values(k0, k1)`` is a sparse (nnz, k1 - k0) matrix whose column j holds matrix
    k0 + j on the pattern, so a linear combination of the matrices is one sparse product.
    """

    def __init__(self, n, mats):
        rows, cols, data, which = _triplets(mats)
        rows = np.concatenate([rows, np.arange(n)])  # the diagonal always
        cols = np.concatenate([cols, np.arange(n)])
        key = cols.astype(np.int64) * n + rows          # column-major, as CSC stores it
        uniq, pos = np.unique(key, return_inverse=True)
        self.rows, self.cols = (uniq % n).astype(int), (uniq // n).astype(int)
        self.P = sp.csc_matrix((np.ones(uniq.size), (self.rows, self.cols)), shape=(n, n))
        self.P.sort_indices()
        m = data.size
        self.V = sp.csc_matrix((data, (pos[:m], which)), shape=(uniq.size, len(mats)))

    def values(self, k0, k1):
        return sp.csc_matrix(self.V[:, k0:k1])

    def value(self, k):
        return self.V[:, k].toarray().ravel()


class _Bilinear:
    """lambda_c^T A_i q for a list of fixed sparse A_i, touching only their nonzero rows.

    The nonzero rows of all A_i are stacked into one sparse matrix (row t belongs to
    matrix seg[t] and is row rows[t] of it), so every product is one sparse call.
    """

    def __init__(self, mats, n):
        self.k = len(mats)
        r, c, v, which = _triplets(mats)
        if not v.size:
            self.A = None
            return
        key, pos = np.unique(which.astype(np.int64) * n + r, return_inverse=True)
        self.rows = (key % n).astype(int)
        seg = (key // n).astype(int)
        self.A = sp.csr_matrix((v, (pos, c)), shape=(key.size, n))
        self.S = sp.csr_matrix((np.ones(key.size), (seg, np.arange(key.size))),
                               shape=(self.k, key.size))

    def __call__(self, Q, Lam):
        """Q (n, N), Lam (n, n_ch, N) -> (k, n_ch, N)."""
        n_ch, N = Lam.shape[1], Lam.shape[2]
        out = np.zeros((self.k, n_ch, N), complex)
        if self.A is None:
            return out
        AQ = self.A @ Q
        for c in range(n_ch):
            out[:, c, :] = self.S @ (Lam[self.rows, c, :] * AQ)
        return out


class SparseFRF:
    """Residuals of Eqn 25a and their Jacobian for one system, damping and parameter set.

    Parameters
    ----------
    system : nlp.frf.backends.system.LinearSystem
    damping : a damping model with ``structure`` (:mod:`nlp.model.damping`)
    params : nlp.model.parameters.ParameterSet
    target : nlp.solve.problem.Target (channels' outputs and the frequency grid)
    residual : {"log_magnitude", "magnitude", "complex"}
    """

    def __init__(self, system, damping, params, target, residual):
        self.sys, self.params, self.residual = system, params, residual
        self.n = n = system.n
        self.T, self.c = params.T, params.c
        sa, sb, sd = params.slices()
        self.sa, self.sb, self.sd = sa, sb, sd
        self.na, self.nb = sa.stop - sa.start, sb.stop - sb.start
        self.power = np.array([POWER[ch.output] for ch in target.channels])
        self.absolute = np.array([ch.output == "absolute_accelerance" for ch in target.channels])
        # damping structure (cM, cK, S, g) and its Jacobian in theta_d, one small SX function
        nd = sd.stop - sd.start
        th = ca.SX.sym("th", nd)
        cM, cK, S, g = damping.structure(th)
        self.m = 0 if S is None else system.U.shape[1]
        self.nD = len(g)
        parts = [ca.SX(cM), ca.SX(cK)] + ([ca.vec(ca.SX(S))] if S is not None else []) + \
            [ca.SX(gj) for gj in g]
        out = ca.vertcat(*parts)
        self._damp = ca.Function("damping_structure", [th], [out, ca.jacobian(out, th)])
        # the pattern of Z: K0, M0, K_r, M_r, D_j
        mats = [system.K0, system.M0, *system.K_infl, *system.M_infl, *system.dashpots]
        self.pat = _Pattern(n, mats)
        na, nb = len(system.K_infl), len(system.M_infl)
        self.VK = self.pat.values(2, 2 + na)
        self.VM = self.pat.values(2 + na, 2 + na + nb)
        self.VD = self.pat.values(2 + na + nb, len(mats))
        self.K0v, self.M0v = self.pat.value(0), self.pat.value(1)
        # Sensitivities per decision variable z_j, not per parameter: dZ/dz_j uses the
        # aggregated matrices sum_i T_ij K_i and sum_i T_ij M_i (Eqns 23-24 are linear), so a
        # tied group of thousands of stories costs one bilinear form (measured: n = 2000).
        Ta, Tb, Td = self.T[sa], self.T[sb], self.T[sd]
        self.z_a = np.nonzero(np.any(Ta != 0, axis=0))[0]
        self.z_b = np.nonzero(np.any(Tb != 0, axis=0))[0]
        self.free_d = np.nonzero(np.any(Td != 0, axis=1))[0]
        self.Td_free = np.ascontiguousarray(Td[self.free_d].T)  # (n_z, free damping)
        self.bil_K = _Bilinear(_aggregate(system.K_infl, Ta[:, self.z_a], n), n)
        self.bil_M = _Bilinear(_aggregate(system.M_infl, Tb[:, self.z_b], n), n)
        self.bil_D = _Bilinear(system.dashpots, n)
        self.B_infl = np.array(system.b_infl).reshape(len(system.b_infl), n)
        self.B_z = Tb[:, self.z_b].T @ self.B_infl if self.nb else np.zeros((0, n))
        self._choose_solver()
        self._last = None

    # ----------------------------------------------------------- linear solves
    def _choose_solver(self):
        n, pat = self.n, self.pat
        m = self.m
        # small, or small and dense (a projected reduced system): one batched LU
        self.batched = n + m <= BATCH_MAX or (n + m <= 300 and pat.P.nnz >= 0.25 * n * n)
        # bordered pattern [[Z_s, B], [U^T, -I]] (entry order: Z_s, B, U^T, -I)
        i_u = np.repeat(np.arange(n), m)
        a_u = np.tile(np.arange(m), n)
        rows = np.concatenate([pat.rows, i_u, n + a_u, n + np.arange(m)])
        cols = np.concatenate([pat.cols, n + a_u, i_u, n + np.arange(m)])
        if self.batched:
            self.banded = False
            self.bandwidth = n + m
            self._dense_rows, self._dense_cols = rows, cols
            return
        perm = csgraph.reverse_cuthill_mckee(sp.csr_matrix(pat.P), symmetric_mode=True)
        inv = np.empty(n, int)
        inv[perm] = np.arange(n)
        pr, pc = inv[pat.rows], inv[pat.cols]
        bw = int(np.max(np.abs(pr - pc))) if pat.P.nnz else 0
        self.banded = self.m == 0 and bw <= BAND_MAX
        self.bandwidth = bw
        if self.banded:
            self.perm, self.bw = perm, bw
            self.band_index = (bw + pr - pc) * n + pc  # flat index into the (2 bw + 1, n) storage
            return
        self.perm = None
        if m == 0:
            # Reverse Cuthill-McKee order and no pivoting: Z = K - w^2 M + jwC has -jZ with a
            # positive definite Hermitian part (wC), so no pivot vanishes; SuperLU then factorises
            # in ~0.08 s where its own orderings take 0.3-8 s (measured, 3-D frame of 2,100 DOFs)
            self.perm = perm
            rows, cols = pr, pc
        order = np.lexsort((rows, cols))
        self._csc_order = order
        self._csc_rows = rows[order]
        self._csc_indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n + m))])

    def _factor_solve(self, zvals, w, US, rhs):
        """Solve Z_k X_k = rhs at every frequency: zvals (nnz, N); returns (n, n_rhs, N)."""
        n, N = self.n, w.size
        m = self.m
        if self.batched:
            Z = np.zeros((N, n + m, n + m), complex)
            blocks = [zvals.T]
            if m:
                blocks += [(1j * w[:, None] * US.ravel()[None, :]),
                           np.broadcast_to(self.sys.U.ravel(), (N, n * m)),
                           np.full((N, m), -1.0)]
            Z[:, self._dense_rows, self._dense_cols] = np.concatenate(blocks, axis=1)
            rhs_b = np.vstack([rhs, np.zeros((m, rhs.shape[1]))])
            X = np.linalg.solve(Z, np.broadcast_to(rhs_b, (N, *rhs_b.shape)))
            return X[:, :n, :].transpose(1, 2, 0)
        X = np.empty((n, rhs.shape[1], N), complex)
        if self.banded:
            rp = rhs[self.perm]
            for k in range(N):
                ab = np.zeros((2 * self.bw + 1) * n, complex)
                ab[self.band_index] = zvals[:, k]
                X[self.perm, :, k] = sla.solve_banded((self.bw, self.bw), ab.reshape(-1, n), rp,
                                                      check_finite=False)
            return X
        size = n + m
        if self.perm is not None:  # RCM-ordered pattern, factorised without pivoting
            rp = rhs[self.perm]
            opts = {"SymmetricMode": True}
            for k in range(N):
                A = sp.csc_matrix((zvals[self._csc_order, k], self._csc_rows, self._csc_indptr),
                                  shape=(size, size))
                X[self.perm, :, k] = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                               options=opts).solve(rp)
            return X
        rhs_b = np.vstack([rhs, np.zeros((m, rhs.shape[1]))])
        minus_i = -np.ones(m)
        Ut = self.sys.U.ravel() if m else np.zeros(0)
        for k in range(N):
            data = np.concatenate([zvals[:, k], (1j * w[k] * US).ravel() if m else [],
                                   Ut, minus_i])[self._csc_order]
            A = sp.csc_matrix((data, self._csc_rows, self._csc_indptr), shape=(size, size))
            X[:, :, k] = spla.splu(A, permc_spec="MMD_AT_PLUS_A").solve(rhs_b)[:n]
        return X

    # --------------------------------------------------------------- evaluate
    def _theta(self, z):
        return self.T @ z + self.c

    def frf(self, z, w, jacobian=False):
        """Channel FRFs (n_ch, N) at circular frequencies w; with ``jacobian`` also dH/dz."""
        sys = self.sys
        theta = self._theta(np.asarray(z, float).ravel())
        alpha, beta, td = theta[self.sa], theta[self.sb], theta[self.sd]
        d_out, d_jac = self._damp(td)
        d_out, d_jac = np.asarray(d_out).ravel(), np.asarray(d_jac)
        cM, cK = d_out[0], d_out[1]
        m = self.m
        S = d_out[2:2 + m * m].reshape(m, m, order="F") if m else None
        g = d_out[2 + m * m:]
        vK = self.K0v + self.VK @ alpha
        vM = self.M0v + self.VM @ beta
        vD = self.VD @ g if self.nD else 0.0
        jw = 1j * w
        zvals = (vK[:, None] * (1 + jw * cK) + vM[:, None] * (-(w ** 2) + jw * cM)
                 + jw * (vD[:, None] if self.nD else 0.0))
        b = sys.b0 + (self.B_infl.T @ beta if self.nb else 0.0)
        rhs = np.column_stack([b, sys.E]) if jacobian else b[:, None]
        X = self._factor_solve(zvals, w, sys.U @ S if m else None, rhs.astype(complex))
        q = X[:, 0, :]
        Hq = sys.E.T @ q
        fac = (jw[None, :]) ** self.power[:, None]
        H = fac * Hq + self.absolute[:, None]
        if not jacobian:
            return H
        Lam = X[:, 1:, :]
        dHz = np.zeros((self.params.n_z, Hq.shape[0], w.size), complex)
        dHz[self.z_a] = -(1 + jw * cK) * self.bil_K(q, Lam)
        if self.z_b.size:
            dHz[self.z_b] += (-(-(w ** 2) + jw * cM) * self.bil_M(q, Lam)
                              + np.einsum("rn,nck->rck", self.B_z, Lam))
        if self.free_d.size:
            P = self.pat.P
            M = sp.csc_matrix((vM, P.indices, P.indptr), shape=P.shape)
            K = sp.csc_matrix((vK, P.indices, P.indptr), shape=P.shape)
            PM = np.einsum("nck,nk->ck", Lam, M @ q)
            PK = np.einsum("nck,nk->ck", Lam, K @ q)
            dB = d_jac[0][:, None, None] * PM + d_jac[1][:, None, None] * PK
            if m:
                Ul, Uq = np.einsum("na,nck->ack", sys.U, Lam), sys.U.T @ q
                # vec(S) is column-major: entry (a, b) at a + m b
                O = np.einsum("ack,bk->back", Ul, Uq).reshape(m * m, *Ul.shape[1:])
                dB = dB + np.einsum("sj,sck->jck", d_jac[2:2 + m * m], O)
            if self.nD:
                dB = dB + np.einsum("lj,lck->jck", d_jac[2 + m * m:], self.bil_D(q, Lam))
            dD = -jw * dB[self.free_d]
            # a complex array viewed as interleaved floats: one contiguous real BLAS product
            flat = np.ascontiguousarray(dD.reshape(dD.shape[0], -1)).view(float)
            dHz += np.ascontiguousarray(self.Td_free @ flat).view(complex).reshape(dHz.shape)
        dHz *= fac[None]
        return H, dHz

    def residuals(self, z, data, jacobian=True):
        """(r, J) ordered like the dense backend: frequency-major, channel-minor."""
        w, yr, yi, s, wt = data
        Y = yr + 1j * yi
        out = self.frf(z, w, jacobian)
        H, dH = out if jacobian else (out, None)
        if self.residual == "log_magnitude":
            R = wt * (np.log(np.abs(H)) - np.log(np.abs(Y)))
            D = wt * (dH / H).real if jacobian else None
        elif self.residual == "magnitude":
            R = wt * (np.abs(H) - np.abs(Y)) / s
            D = wt * (np.conj(H) * dH).real / (np.abs(H) * s) if jacobian else None
        else:
            E = (H - Y) / s
            R = np.stack([wt * E.real, wt * E.imag], axis=1).reshape(-1, E.shape[1])
            D = (np.stack([wt * (dH / s).real, wt * (dH / s).imag], axis=2)
                 .reshape(dH.shape[0], -1, dH.shape[2]) if jacobian else None)
        r = R.ravel(order="F")
        if not jacobian:
            return r, None
        J = D.transpose(0, 2, 1).reshape(D.shape[0], -1).T  # rows: k-major, channel-minor
        return r, J

    def cached(self, z, data_key, data):
        """(r, J) at z, reused while IPOPT asks for f, grad and Hessian at the same point."""
        z = np.asarray(z, float).ravel()
        if self._last is not None and self._last[1] == data_key and np.array_equal(self._last[0], z):
            return self._last[2]
        out = self.residuals(z, data, jacobian=True)
        self._last = (z.copy(), data_key, out)
        return out
