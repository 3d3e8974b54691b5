"""Exact FRF and its analytic sensitivities with one sparse factorisation per frequency.

For each frequency w_k the system of :mod:`nlp.frf.backends.system` is
factorised once (small systems, e.g. a projected reduced one: one eigendecomposition per
evaluation, :mod:`nlp.frf.backends.pencil`, else one batched dense LU over all frequencies;
else, when the band is narrow after reverse Cuthill-McKee ordering, one batched
banded L D L^T over a chunk of frequencies (:mod:`nlp.frf.backends.banded`:
no pivoting, growth-checked, LAPACK with pivoting where the check fails),
SuperLU on the same ordering without pivoting otherwise (a minimum-degree
ordering with pivoting for the bordered damping system); a rank-m
damping term U S U^T enters as a bordered system [[Z_s, jw U S], [U^T, -I]],
so C never fills Z in). The same factors give

    q = Z^-1 b                       (the FRF of every DOF, Eqns 2-5)
    lambda_c = Z^-1 e_c              (adjoint of channel c; Z is symmetric)
    dH_c / dtheta_i = lambda_c^T (db/dtheta_i - dZ/dtheta_i q)

and dZ/dtheta_i is a fixed sparse matrix times a scalar (M and K are linear
in alpha and beta, Eqns 23-24), so each sensitivity is a sparse bilinear form:
the cost is (1 + n_channels) solves per frequency whatever the number of
parameters. Frequencies run in chunks (memory flat in N); J is formed in real
arithmetic, chunk by chunk (:meth:`SparseFRF.residuals`). Runs in numpy/scipy
and enters the CasADi NLP as callbacks.
"""

from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla
import casadi as ca

from nlp.frf.backends.allocator import retain_freed_memory
from nlp.frf.backends.banded import solve_banded_batch, solve_pivoted
from nlp.frf.backends.pencil import decompose, on_pattern, span, stand_in, update
from nlp.frf.backends.bilinear import Bilinear, Pattern, aggregate, real_times_complex
from nlp.frf.backends.terms import terms_state
from nlp.frf.forms import POWER

__all__ = ["SparseFRF", "BAND_MAX"]

BAND_MAX = 40  # half-bandwidth up to which the banded LU beats SuperLU (measured at n = 2000)
BATCH_MAX = 24  # up to this size one batched dense LU over all frequencies beats the banded LU (measured)
# a dense pattern (a projected reduced system, concatenated bases included) is solved by LAPACK's
# dense LU up to this size, over frequency blocks of at most BATCH_BYTES: at sizes 250, 320 and
# 450 one complex solve took 4.4, 8.1 and 20 ms against 18, 26 and 56 ms for SuperLU (one thread)
DENSE_MAX_LU = 1500
BATCH_BYTES = 64e6
CHUNK_BYTES = 2 ** 24  # working memory of one chunk of frequencies: 16 MiB keeps it near the caches (measured)
CHUNK_MIN = 256  # frequencies per chunk at least: each of the n steps of a banded pass then does real work
UPDATE_SHARE = 0.25  # the families' terms solved as a low-rank update up to this rank / n (pencil.update)


def _span(ix):
    """A slice for a run of consecutive indices (a view, not a copy, when indexing), else ix."""
    if ix.size and np.array_equal(ix, np.arange(ix[0], ix[0] + ix.size)):
        return slice(int(ix[0]), int(ix[0]) + ix.size)
    return ix


class SparseFRF:
    """Residuals of Eqn 25a and their Jacobian for one system, damping and parameter set.

    Parameters
    ----------
    system : nlp.frf.backends.system.LinearSystem
    damping : a damping model with ``structure`` (:mod:`nlp.model.damping`)
    params : nlp.model.parameters.ParameterSet
    target : nlp.solve.problem.Target (channels' outputs and the frequency grid)
    residual : {"log_magnitude", "magnitude", "relative_magnitude", "complex"}
    terms : nlp.frf.backends.terms.Terms, optional
        Added physics: sparse terms on the model's DOFs and the extra DOFs it appends.
    """

    def __init__(self, system, damping, params, target, residual, terms=None):
        if terms is not None:
            system = system.padded(terms.n_extra)
        self.terms = terms
        self.nT = 0 if terms is None else len(terms.P)
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
        mats = [system.K0, system.M0, *system.K_infl, *system.M_infl, *system.dashpots,
                *(terms.P if self.nT else ())]
        self.pat = Pattern(n, mats)
        na, nb = len(system.K_infl), len(system.M_infl)
        self.VK = self.pat.values(2, 2 + na)
        self.VM = self.pat.values(2 + na, 2 + na + nb)
        self.VD = self.pat.values(2 + na + nb, len(mats) - self.nT)
        self.VT = self.pat.values(len(mats) - self.nT, len(mats))
        self.bil_T = Bilinear(terms.P, n) if self.nT else None
        self.T_seg = self.bil_T.S.tocsc().indices if self.nT and self.bil_T.A is not None else None
        self.K0v, self.M0v = self.pat.value(0), self.pat.value(1)
        # Sensitivities per decision variable z_j, not per parameter: dZ/dz_j uses the
        # aggregated matrices sum_i T_ij K_i and sum_i T_ij M_i (Eqns 23-24 are linear), so a
        # tied group of thousands of stories costs one bilinear form (measured: n = 2000).
        Ta, Tb, Td = self.T[sa], self.T[sb], self.T[sd]
        self.z_a = np.nonzero(np.any(Ta != 0, axis=0))[0]
        self.z_b = np.nonzero(np.any(Tb != 0, axis=0))[0]
        self.free_d = np.nonzero(np.any(Td != 0, axis=1))[0]
        Td_free = Td[self.free_d].T  # (n_z, free damping)
        self.z_d = np.nonzero(np.any(Td_free != 0, axis=1))[0]
        self.Td_free = np.ascontiguousarray(Td_free[self.z_d])
        self.at = [_span(x) for x in (self.z_a, self.z_b, self.z_d)]  # where J's columns go
        self.bil_K = Bilinear(aggregate(system.K_infl, Ta[:, self.z_a], n), n)
        self.bil_M = Bilinear(aggregate(system.M_infl, Tb[:, self.z_b], n), n)
        self.bil_D = Bilinear(system.dashpots, n)
        self.B_infl = np.array(system.b_infl).reshape(len(system.b_infl), n)
        # db/dz: sparse (ground input -M_r r has the few nonzeros of M_r)
        self.B_z = sp.csr_matrix(Tb[:, self.z_b].T @ self.B_infl if self.nb else np.zeros((0, n)))
        self._choose_solver()
        self._Q = self._term_span()
        self.fallbacks = 0  # frequencies re-solved with pivoting (batched banded path)
        self._last = None
        retain_freed_memory()  # each evaluation reuses the last one's memory, no page faults

    # ----------------------------------------------------------- linear solves
    def _choose_solver(self):
        n, pat = self.n, self.pat
        m = self.m
        # small, or small and dense (a projected reduced system): one batched LU
        self.batched = n + m <= BATCH_MAX or (n + m <= DENSE_MAX_LU and pat.P.nnz >= 0.25 * n * n)
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
        self.banded = self.m == 0 and bw <= BAND_MAX and pat.symmetric
        self.bandwidth = bw
        if self.banded:
            # symmetric: the lower band (p = row - col >= 0) of the RCM-ordered Z is enough
            self.perm, self.inv, self.bw = perm, inv, bw
            entries = np.nonzero(pr >= pc)[0]
            index = (pr - pc)[entries] * n + pc[entries]
            order = np.argsort(index)  # in storage order: a run of slots is written as a slice
            self.band_entries, self.band_index = entries[order], _span(index[order])
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

    def _band(self, st, w):
        """The lower band of the RCM-ordered Z_k = K - w_k^2 M + j w_k C at frequencies w,
        (b+1, n, N_c) complex (:func:`nlp.frf.backends.banded.lower_band`). C = cM M + cK K
        (+ dashpots) is real, so the real and imaginary parts are formed in real arithmetic
        on the band's entries only: the same numbers as the complex products of every
        pattern entry, at a fraction of the work."""
        e = self.band_entries
        vK, vM = st.vK[e, None], st.vM[e, None]
        im = vK * (w * st.cK) + vM * (w * st.cM)
        if self.nD:
            im += w * st.vD[e, None]
        re = vK + vM * (-(w ** 2))
        if self.nT:  # the families' terms: K - w^2 M real, w C + Kh imaginary
            tv = st.tv[:, e]
            re = re + tv[0][:, None] - tv[1][:, None] * w ** 2
            im = im + tv[2][:, None] * w + tv[3][:, None]
        L = np.zeros(((self.bw + 1) * self.n, w.size), complex)
        L.real[self.band_index] = re
        L.imag[self.band_index] = im
        return L.reshape(self.bw + 1, self.n, -1)

    def _banded_solve(self, st, w, rhs):
        """Z_k X_k = rhs by the batched banded L D L^T (:mod:`nlp.frf.backends.banded`),
        LAPACK with pivoting where its growth check fails; rhs (n, n_rhs) -> (n_rhs, n, N)."""
        rp = rhs[self.perm]
        Xp, bad = solve_banded_batch(self._band(st, w), rp)
        if bad.size:  # growth check failed: LAPACK with pivoting at those frequencies
            Lb = self._band(st, w[bad])
            for i, k in enumerate(bad):
                Xp[:, :, k] = solve_pivoted(Lb[:, :, i], rp)
            self.fallbacks += bad.size
        X = np.empty((rhs.shape[1], self.n, w.size), complex)
        for r in range(X.shape[0]):  # rows of N contiguous values: a fast gather
            X[r] = Xp[self.inv, r]
        return X

    def _factor_solve(self, zvals, w, US, rhs):
        """Solve Z_k X_k = rhs at every frequency: zvals (nnz, N), rhs (n, n_rhs);
        returns X (n_rhs, n, N)."""
        n, N = self.n, w.size
        m = self.m
        if self.batched:
            rhs_b = np.vstack([rhs, np.zeros((m, rhs.shape[1]))])
            X = np.empty((rhs.shape[1], n, N), complex)
            step = max(1, int(BATCH_BYTES // (16 * (n + m) ** 2)))  # memory stays flat
            for a in range(0, N, step):
                k = slice(a, min(N, a + step))
                wk = w[k]
                Z = np.zeros((wk.size, n + m, n + m), complex)
                blocks = [zvals[:, k].T]
                if m:
                    blocks += [(1j * wk[:, None] * US.ravel()[None, :]),
                               np.broadcast_to(self.sys.U.ravel(), (wk.size, n * m)),
                               np.full((wk.size, m), -1.0)]
                Z[:, self._dense_rows, self._dense_cols] = np.concatenate(blocks, axis=1)
                Xk = np.linalg.solve(Z, np.broadcast_to(rhs_b, (wk.size, *rhs_b.shape)))
                X[:, :, k] = Xk[:, :n, :].transpose(2, 1, 0)
            return X
        X = np.empty((rhs.shape[1], n, N), complex)
        size = n + m
        if self.perm is not None:  # RCM-ordered pattern, factorised without pivoting
            rp = rhs[self.perm]
            opts = {"SymmetricMode": True}
            for k in range(N):
                A = sp.csc_matrix((zvals[self._csc_order, k], self._csc_rows, self._csc_indptr),
                                  shape=(size, size))
                X[:, self.perm, k] = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                               options=opts).solve(rp).T
            return X
        rhs_b = np.vstack([rhs, np.zeros((m, rhs.shape[1]))])
        minus_i = -np.ones(m)
        Ut = self.sys.U.ravel() if m else np.zeros(0)
        for k in range(N):
            data = np.concatenate([zvals[:, k], (1j * w[k] * US).ravel() if m else [],
                                   Ut, minus_i])[self._csc_order]
            A = sp.csc_matrix((data, self._csc_rows, self._csc_indptr), shape=(size, size))
            X[:, :, k] = spla.splu(A, permc_spec="MMD_AT_PLUS_A").solve(rhs_b)[:n].T
        return X

    def _pencil_solve(self, st, w, rhs):
        """Solves by one eigendecomposition per evaluation (:mod:`nlp.frf.backends.pencil`; low-rank
        families: an update of the base's), or None where not accurate (then LU per frequency)."""
        if "pencil" not in vars(st):
            A = self._dense(st)
            st.pencil = None
            if self._Q is not None:
                B = stand_in(self._dense(st, False), self.terms.n_extra, st.cK, st.cM)
                st.pencil = update(decompose(*B, w, rhs), self._Q, A, w, rhs)
            if st.pencil is None:
                st.pencil = decompose(*A, w, rhs)
        return None if st.pencil is None else st.pencil.solve(w, rhs)

    def _dense(self, st, terms=True):
        """Dense A0, A1, A2 of Z = A0 + j w A1 - w^2 A2 at one evaluation (``terms``: with the
        families')."""
        vals = [st.vK, st.cK * st.vK + st.cM * st.vM, st.vM]
        if self.nD:
            vals[1] = vals[1] + st.vD
        if self.nT and terms:
            vals = [vals[0] + st.tv[0] + 1j * st.tv[3], vals[1] + st.tv[2], vals[2] + st.tv[1]]
        A = [on_pattern(self.n, self.pat.rows, self.pat.cols, v) for v in vals]
        if self.m:  # the bordered rank-m damping, folded back into C: U S U^T
            A[1] = A[1] + st.US @ self.sys.U.T
        return A

    def _term_span(self):
        """Q spanning the families' terms and extra DOFs (pencil route, Rayleigh damping), or
        None above rank ``UPDATE_SHARE`` n."""
        if not (self.nT and self.batched and not self.m and not self.nD):
            return None
        Q = span(self.terms.P, extra=self.terms.n_extra)
        return Q if Q is not None and Q.shape[1] <= UPDATE_SHARE * self.n else None

    def _chunks(self, N, n_res):
        """Slices of the frequency axis whose working arrays fit in ``CHUNK_BYTES``."""
        n, nz, size = self.n, self.params.n_z, self.n + self.m
        n_rhs = 1 + len(self.power)
        per = 3 * n_rhs * size + 2 * (getattr(self, "bw", 0) + 1) * n + 3 * nz * n_res
        per += size * size if self.batched else 0
        step = max(CHUNK_MIN, CHUNK_BYTES // (16 * per))
        return [slice(k, min(k + step, N)) for k in range(0, N, step)]

    # --------------------------------------------------------------- evaluate
    def _state(self, z):
        """The scalars of Eqns 23-24 and of the damping structure at z (one namespace)."""
        theta = self.T @ np.asarray(z, float).ravel() + self.c
        alpha, beta, td = theta[self.sa], theta[self.sb], theta[self.sd]
        d_out, d_jac = self._damp(td)
        d_out, d_jac = np.asarray(d_out).ravel(), np.asarray(d_jac)
        m = self.m
        S = d_out[2:2 + m * m].reshape(m, m, order="F") if m else None
        g = d_out[2 + m * m:]
        st = SimpleNamespace(
            cM=d_out[0], cK=d_out[1], S=S, d_jac=d_jac, US=self.sys.U @ S if m else None,
            vK=self.K0v + self.VK @ alpha, vM=self.M0v + self.VM @ beta,
            vD=self.VD @ g if self.nD else None,
            b=self.sys.b0 + (self.B_infl.T @ beta if self.nb else 0.0))
        st.theta = theta
        if self.terms is not None:
            terms_state(st, self.terms, self.VT, self.T)
        return st

    def _solve(self, st, w, jacobian):
        """q (n, N) and, with ``jacobian``, the adjoints Lam (n_ch, n, N) at frequencies w."""
        rhs = (np.column_stack([st.b, self.sys.E]) if jacobian else st.b[:, None]).astype(complex)
        if self.banded:
            X = self._banded_solve(st, w, rhs)
            return X[0], X[1:]
        if self.batched:
            X = self._pencil_solve(st, w, rhs)
            if X is not None:
                return X[0], X[1:]
        jw = 1j * w
        zvals = (st.vK[:, None] * (1 + jw * st.cK) + st.vM[:, None] * (-(w ** 2) + jw * st.cM))
        if self.nD:
            zvals += jw * st.vD[:, None]
        if self.nT:
            zvals += st.tv[0][:, None] - st.tv[1][:, None] * w ** 2 + st.tv[2][:, None] * jw \
                + 1j * st.tv[3][:, None]
        X = self._factor_solve(zvals, w, st.US, rhs)
        return X[0], X[1:]

    def _damping_terms(self, st, q, Lam):
        """d(lambda_c^T Z q)/d theta_d / (j w) for the free damping parameters, (free, n_ch, N)."""
        if "MK" not in vars(st):  # M and K at z, built once per evaluation
            P = self.pat.P
            st.MK = tuple(sp.csc_matrix((v, P.indices, P.indptr), shape=P.shape)
                          for v in (st.vM, st.vK))
        M, K = st.MK
        PM = (Lam * real_times_complex(M, q)[None]).sum(axis=1)
        PK = (Lam * real_times_complex(K, q)[None]).sum(axis=1)
        dj, m = st.d_jac, self.m
        dB = dj[0][:, None, None] * PM + dj[1][:, None, None] * PK
        if m:
            U = self.sys.U
            Ul = np.stack([U.T @ L for L in Lam], axis=1)   # (m, n_ch, N)
            Uq = U.T @ q
            # vec(S) is column-major: entry (a, b) at a + m b
            O = (Ul[None] * Uq[:, None, None, :]).reshape(m * m, *Ul.shape[1:])
            dB = dB + np.tensordot(dj[2:2 + m * m].T, O, axes=1)
        if self.nD:
            dB = dB + np.tensordot(dj[2 + m * m:].T, self.bil_D(q, Lam), axes=1)
        return dB[self.free_d]

    def _dHq(self, st, w, q, Lam):
        """d(E^T q)/dz, (n_z, n_ch, N): Eqns 23-24 as bilinear forms lambda_c^T (db - dZ q)."""
        n_ch = Lam.shape[0]
        D = np.zeros((self.params.n_z, 2 * n_ch, w.size))
        fac = np.ones((2 * n_ch, w.size), complex)
        fac[1::2] = -1j                               # Re(-j x) = Im(x)
        self._jacobian_into(D, st, w, q, Lam, fac, np.repeat(np.arange(n_ch), 2))
        return D[:, 0::2] + 1j * D[:, 1::2]

    def _jacobian_into(self, D, st, w, q, Lam, G, ch):
        """D[z, i, k] += Re(G[i, k] d(E^T q)_{ch[i]}/dz_z) at frequencies w: D (n_z, n_res, N).

        Real arithmetic where it can: the weight G folds into the adjoint (Lg), the group
        coefficients into A q, and each bilinear form's real part is taken before its sum.
        """
        jw = 1j * w
        AK = self.bil_K.products(q) * (-(1 + jw * st.cK)) if self.z_a.size else None
        AM = self.bil_M.products(q) * (w ** 2 - jw * st.cM) if self.z_b.size else None
        dD = self._damping_terms(st, q, Lam) * (-jw) if self.z_d.size else None
        AT = None  # the families' terms: -f_t(w) P_t q on their stacked rows
        if self.T_seg is not None:
            AT = self.bil_T.products(q) * (-self.terms.factors(w)[self.T_seg])
        at_a, at_b, at_d = self.at
        for i, c in enumerate(ch):
            out, Lg = D[:, i], Lam[c] * G[i]
            if AK is not None:
                out[at_a] += self.bil_K.real_form(AK, Lg)
            if AM is not None:
                out[at_b] += self.bil_M.real_form(AM, Lg) + self.B_z @ Lg.real
            if dD is not None:
                out[at_d] += self.Td_free @ (dD[:, c] * G[i]).real
            if AT is not None:
                out += st.dcz.T @ (self.bil_T.real_form(AT, Lg) + self.terms.b @ Lg.real)

    def _channels(self, st, w, jacobian):
        """(H (n_ch, N), fac (n_ch, N), q, Lam, dth): H = fac E^T q + absolute, then the output
        families (F, dth: :mod:`nlp.frf.backends.outputs`; fac includes F); Lam None
        without ``jacobian``."""
        q, Lam = self._solve(st, w, jacobian)
        fac = (1j * w[None, :]) ** self.power[:, None]
        H = fac * (self.sys.E.T @ q) + self.absolute[:, None]
        dth = {}
        if self.terms is not None and self.terms.outputs is not None:
            H, F, dth = self.terms.outputs(st.theta, w, H)
            fac = fac * F
        return H, fac, q, Lam, dth

    def frf(self, z, w, jacobian=False):
        """Channel FRFs (n_ch, N) at circular frequencies w; with ``jacobian`` also dH/dz."""
        st, w = self._state(z), np.asarray(w, float)
        H, fac, q, Lam, dth = self._channels(st, w, jacobian)
        if not jacobian:
            return H
        dH = self._dHq(st, w, q, Lam) * fac[None]
        for c, d in dth.items():
            dH[:, c, :] += self.T.T @ d
        return H, dH

    def _rows(self, H, Y, s, wt):
        """Residual rows R (n_res, N) of Eqn 25a and Gh with dR/dz = Re(Gh dH/dz)."""
        if self.residual == "log_magnitude":
            return wt * (np.log(np.abs(H)) - np.log(np.abs(Y))), wt / H
        if self.residual in ("magnitude", "relative_magnitude"):  # they differ in s only
            aH = np.abs(H)
            return wt * (aH - np.abs(Y)) / s, wt * np.conj(H) / (aH * s)
        E = (H - Y) / s
        R = np.stack([wt * E.real, wt * E.imag], axis=1).reshape(-1, E.shape[1])
        G = np.stack([wt / s, -1j * wt / s], axis=1).reshape(-1, E.shape[1])
        return R, G  # Im(x) = Re(-j x)

    def _chunk_rows(self, z, data, jacobian, Jt=None):
        """(slice, R (n_res, N_c), D (n_z, n_res, N_c) or None) per chunk of frequencies
        (``CHUNK_BYTES``): the residual rows of Eqn 25a and their derivatives. With ``Jt``
        (n_z, N, n_res), zero, D is its chunk seen as (n_z, n_res, N_c): J is summed in
        place, with no copy."""
        w, yr, yi, s, wt = data
        n_ch, N, nz = len(self.power), w.size, self.params.n_z
        n_res = n_ch * (2 if self.residual == "complex" else 1)
        ch = np.arange(n_res) // (n_res // n_ch)
        st = self._state(z)
        for sl in self._chunks(N, n_res):
            H, fac, q, Lam, dth = self._channels(st, w[sl], jacobian)
            R, Gh = self._rows(H, yr[:, sl] + 1j * yi[:, sl], s[:, sl], wt[:, sl])
            D = None
            if jacobian:
                # G = Gh dH/d(E^T q); the data arrive column-major: G[i] must be contiguous
                G = np.ascontiguousarray(Gh * fac[ch])
                D = (np.zeros((nz, n_res, sl.stop - sl.start)) if Jt is None
                     else Jt[:, sl].transpose(0, 2, 1))
                self._jacobian_into(D, st, w[sl], q, Lam, G, ch)
                for i, c in enumerate(ch):    # the output families' own parameters
                    if c in dth:
                        D[:, i] += self.T.T @ (dth[c] * Gh[i]).real
            yield sl, R, D

    def residuals(self, z, data, jacobian=True):
        """(r, J) ordered like the dense backend: frequency-major, residual-minor.

        Computed over chunks of frequencies (``CHUNK_BYTES``), written straight into J,
        which is stored column-major (each parameter's column contiguous, as J^T J wants).
        """
        N, nz = data[0].size, self.params.n_z
        n_res = len(self.power) * (2 if self.residual == "complex" else 1)
        r = np.empty(N * n_res)
        Jt = np.zeros((nz, N, n_res)) if jacobian else None
        for sl, R, _ in self._chunk_rows(z, data, jacobian, Jt):
            r[sl.start * n_res:sl.stop * n_res] = R.T.ravel()
        return r, (Jt.reshape(nz, -1).T if jacobian else None)

    def normal_equations(self, z, data):
        """(r, J^T r, J^T J) summed chunk by chunk: J is never held whole (memory flat in N;
        the Gauss-Newton Hessian costs n_z^2 n_res flops per frequency either way)."""
        N, nz = data[0].size, self.params.n_z
        n_res = len(self.power) * (2 if self.residual == "complex" else 1)
        r = np.empty(N * n_res)
        g, A = np.zeros(nz), np.zeros((nz, nz))
        for sl, R, D in self._chunk_rows(z, data, True):
            r[sl.start * n_res:sl.stop * n_res] = R.T.ravel()
            Dm = D.reshape(nz, -1)
            A += Dm @ Dm.T  # one symmetric rank update (numpy calls syrk for X @ X.T)
            g += Dm @ R.ravel()
        return r, g, A

    def cached_value(self, z, data_key, data):
        """r at z without its Jacobian (a line-search trial point: about 1/3 of the cost of
        r and J on a tall frame), or the cached r of :meth:`cached` at the same point."""
        z = np.asarray(z, float).ravel()
        if self._last is not None and self._last[1] == data_key and np.array_equal(self._last[0], z):
            return self._last[2][0]
        return self.residuals(z, data, jacobian=False)[0]

    def cached(self, z, data_key, data):
        """(r, J) at z, reused while IPOPT asks for f, grad and Hessian at the same point."""
        z = np.asarray(z, float).ravel()
        if self._last is not None and self._last[1] == data_key and np.array_equal(self._last[0], z):
            return self._last[2]
        out = self.residuals(z, data, jacobian=True)
        self._last = (z.copy(), data_key, out)
        return out
