"""FRFs of large models by sparse direct solves, for the case generators.

Written apart from the package's FRF code on purpose: the cases' data must not
come from the code they test. H_k = (jw)^p [(K - w^2 M + jwC)^-1 b]_rows.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["frf_sparse", "add_noise"]


def frf_sparse(M, K, C, b, rows, f, power=0):
    """(len(rows), len(f)) complex FRFs; power 0 receptance, 2 accelerance (-w^2 H)."""
    Ms, Ks, Cs = (sp.csc_matrix(A) for A in (M, K, C))
    b = np.asarray(b, complex)
    H = np.empty((len(rows), len(f)), complex)
    for k, fk in enumerate(f):
        w = 2 * np.pi * fk
        q = spla.splu((Ks - w**2 * Ms + 1j * w * Cs).tocsc(), permc_spec="MMD_AT_PLUS_A").solve(b)
        H[:, k] = (1j * w) ** power * q[rows]
    return H


def add_noise(H, noise, rng):
    """H (1 + noise e), e complex Gaussian with E|e|^2 = 1 (noise relative to |H|)."""
    e = (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)) / np.sqrt(2)
    return H * (1 + noise * e)
