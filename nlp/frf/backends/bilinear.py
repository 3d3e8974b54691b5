"""Fixed sparse matrices of the FRF system: their union pattern and their bilinear forms.

The sensitivities of the exact FRF (Eqns 23-24: M and K linear in beta and alpha) are
lambda_c^T A_i q for fixed sparse A_i, every channel c and every frequency. They are
evaluated here for all i, c and a chunk of frequencies with a few sparse products in real
arithmetic (a complex array read as interleaved real pairs: the A_i are real).
"""

import numpy as np
import scipy.sparse as sp

__all__ = ["triplets", "aggregate", "Pattern", "Bilinear", "real_times_complex"]

DENSE_SHARE = 0.25  # stacked rows this full are multiplied as a dense array (one BLAS call)


def triplets(mats):
    """(rows, cols, values, matrix index) of all nonzeros of a list of sparse matrices."""
    parts = []
    for i, A in enumerate(mats):
        A = A if sp.isspmatrix_csc(A) else sp.csc_matrix(A)
        cols = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
        parts.append((A.indices, cols, A.data, np.full(A.data.size, i)))
    if not parts:
        return (np.zeros(0, int),) * 2 + (np.zeros(0),) + (np.zeros(0, int),)
    return tuple(np.concatenate(x) for x in zip(*parts))


def aggregate(mats, W, n):
    """Matrices sum_i W[i, j] A_i, one per column j of W (sparse)."""
    r, c, v, which = triplets(mats)
    out = []
    for j in range(W.shape[1]):
        wv = W[which, j] * v if v.size else v
        keep = wv != 0
        out.append(sp.csc_matrix((wv[keep], (r[keep], c[keep])), shape=(n, n)))
    return out


def real_times_complex(A, X):
    """A @ X for a real (sparse or dense) A and a C-contiguous complex X (n, N): one real
    product on X read as (n, 2N) interleaved floats, half the flops of a complex one."""
    X = np.ascontiguousarray(X)
    out = A @ X.view(float).reshape(X.shape[0], -1)
    return np.ascontiguousarray(out).view(complex)


class Pattern:
    """The union sparsity pattern of fixed matrices, and each one's values on it.

    ``values(k0, k1)`` is a sparse (nnz, k1 - k0) matrix whose column j holds matrix
    k0 + j on the pattern, so a linear combination of the matrices is one sparse product.
    ``symmetric`` says whether every matrix is symmetric (pattern and values).
    """

    def __init__(self, n, mats):
        rows, cols, data, which = triplets(mats)
        rows = np.concatenate([rows, np.arange(n)])  # the diagonal always
        cols = np.concatenate([cols, np.arange(n)])
        key = cols.astype(np.int64) * n + rows          # column-major, as CSC stores it
        uniq, pos = np.unique(key, return_inverse=True)
        self.rows, self.cols = (uniq % n).astype(int), (uniq // n).astype(int)
        self.P = sp.csc_matrix((np.ones(uniq.size), (self.rows, self.cols)), shape=(n, n))
        self.P.sort_indices()
        m = data.size
        self.V = sp.csc_matrix((data, (pos[:m], which)), shape=(uniq.size, len(mats)))
        mirror = np.searchsorted(uniq, self.rows.astype(np.int64) * n + self.cols)
        mirror = np.minimum(mirror, uniq.size - 1)
        self.symmetric = bool(np.array_equal(uniq[mirror], self.rows.astype(np.int64) * n + self.cols)
                              and abs(self.V - self.V[mirror]).max() <= 1e-12 * max(abs(self.V).max(), 1))

    def values(self, k0, k1):
        return sp.csc_matrix(self.V[:, k0:k1])

    def value(self, k):
        return self.V[:, k].toarray().ravel()


class Bilinear:
    """lambda_c^T A_i q for a list of fixed sparse A_i, touching only their nonzero rows.

    The nonzero rows of all A_i are stacked into one sparse matrix (row t belongs to
    matrix seg[t] and is row rows[t] of it), so every product is one sparse call.
    """

    def __init__(self, mats, n):
        self.k = len(mats)
        r, c, v, which = triplets(mats)
        if not v.size:
            self.A = None
            return
        key, pos = np.unique(which.astype(np.int64) * n + r, return_inverse=True)
        self.rows = (key % n).astype(int)
        seg = (key // n).astype(int)
        self.A = sp.csr_matrix((v, (pos, c)), shape=(key.size, n))
        if self.A.nnz >= DENSE_SHARE * key.size * n:  # projected (reduced) matrices: BLAS
            self.A = self.A.toarray()
        self.S = sp.csr_matrix((np.ones(key.size), (seg, np.arange(key.size))),
                               shape=(self.k, key.size))

    def products(self, Q):
        """A_i q on the stacked nonzero rows, (rows, N) complex."""
        return real_times_complex(self.A, Q)

    def real_form(self, AQ, Lam_c):
        """Re(lambda_c^T A_i q) for all i, (k, N); AQ from :meth:`products` (any complex weight
        per frequency folded into Lam_c or AQ)."""
        return self.S @ (Lam_c[self.rows] * AQ).real

    def __call__(self, Q, Lam):
        """Q (n, N), Lam (n_ch, n, N) complex -> (k, n_ch, N)."""
        n_ch, N = Lam.shape[0], Lam.shape[2]
        out = np.zeros((self.k, n_ch, N), complex)
        if self.A is None:
            return out
        AQ = self.products(Q)
        for c in range(n_ch):
            out[:, c, :] = real_times_complex(self.S, Lam[c][self.rows] * AQ)
        return out
