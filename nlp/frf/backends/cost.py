"""A flop-and-memory bound for one residual-plus-Jacobian evaluation of the sparse backend.

Counted per frequency in real flops (a complex multiply-add is 8, a real-by-complex one 4)
and in the bytes that must at least cross memory once, for the batched banded path
(:mod:`nlp.frf.backends.banded`; n unknowns, half-bandwidth b, n_rhs = 1 + n_channels):

    Z values         8 nnz(Z)
    L D L^T          n (4 b^2 + 10 b + 6)
    solves           n_rhs n (16 b + 6)
    growth check     10 n (b + 1)
    sensitivities    4 (nnz A_K + nnz A_M) + n_res (8 (rows A_K + rows A_M) + 4 nnz B_z)
                     + Rayleigh: 8 nnz(Z) + 16 n n_ch     (lambda_c^T M q, lambda_c^T K q)
    J                4 n_z n_res                           (Re(G dH), accumulated)

    bytes            32 nnz(Z) + 48 (b + 1) n + 32 n n_rhs + 8 n_z n_res

(Z values written and read, the band written, read and rewritten by the factorisation, the
solutions written by the solves and read by the sensitivities, J written once.) The bound
is flops / F + bytes / B for a core's peak rate F and memory bandwidth B
(``machine_rates``); docs/method/backends.md ("Cost of one evaluation") gives the figures.
"""

import time

import numpy as np

__all__ = ["evaluation_cost", "machine_rates"]


def evaluation_cost(ev, N, n_res):
    """{"flops": ..., "bytes": ...} of one (r, J) evaluation of a banded SparseFRF ``ev`` at
    N frequencies with n_res residuals per frequency (:class:`SparseFRF.residuals`)."""
    n, n_ch = ev.n, len(ev.power)
    b = ev.bandwidth
    nnz, n_rhs, n_z = ev.pat.P.nnz, 1 + n_ch, ev.params.n_z

    def size(bil):
        return (0, 0) if bil.A is None else (bil.A.nnz, bil.A.shape[0])

    (aK, rK), (aM, rM) = size(ev.bil_K), size(ev.bil_M)
    sens = 4 * (aK + aM) + n_res * (8 * (rK + rM) + 4 * ev.B_z.nnz)
    if ev.z_d.size:
        sens += 8 * nnz + 16 * n * n_ch
    flops = (8 * nnz + n * (4 * b * b + 10 * b + 6) + n_rhs * n * (16 * b + 6)
             + 10 * n * (b + 1) + sens + 4 * n_z * n_res)
    traffic = 32 * nnz + 48 * (b + 1) * n + 32 * n * n_rhs + 8 * n_z * n_res
    return {"flops": float(flops) * N, "bytes": float(traffic) * N}


def machine_rates(size=1500, words=2 ** 25):
    """(F, B): one core's DGEMM rate [flop/s] and numpy copy bandwidth [byte/s], CPU time."""
    a, c = np.random.rand(size, size), np.random.rand(size, size)
    a @ c
    t = time.process_time()
    a @ c
    F = 2.0 * size ** 3 / (time.process_time() - t)
    x, y = np.random.rand(words), np.empty(words)
    np.copyto(y, x)
    t = time.process_time()
    for _ in range(3):
        np.copyto(y, x)
    B = 3 * 2.0 * x.nbytes / (time.process_time() - t)
    return F, B
