"""The FRF as a CasADi expression, for the NLP (Eqns 2-5 at one frequency).

The second block row of (jwA + B) x = P (Eqn 4) gives v = jw q; substituting
in the first leaves the dynamic stiffness (K - w^2 M + jwC) q = F, the Schur
complement of the state-space system, with the same solution q. We solve it in
real arithmetic on (Re, Im) pairs: this is Gaussian elimination on the real
embedding [[Re Z, -Im Z], [Im Z, Re Z]] written out per complex entry, which
keeps the SX graph small (about n^3/3 complex operations). No pivoting is
needed: -jZ = wC - jR has a positive definite Hermitian part wC, so every
leading minor of Z is non-singular.
"""

import casadi as ca

from nlp.frf.forms import POWER

__all__ = ["complex_solve", "frf_symbolic"]


def complex_solve(Zr, Zi, br, bi):
    """Solve (Zr + j Zi) x = br + j bi for SX matrices; returns (xr, xi)."""
    n = Zr.shape[0]
    Ar = [[Zr[i, j] for j in range(n)] for i in range(n)]
    Ai = [[Zi[i, j] for j in range(n)] for i in range(n)]
    yr = [br[i] for i in range(n)]
    yi = [bi[i] for i in range(n)]
    for k in range(n):
        pr, pi = Ar[k][k], Ai[k][k]
        den = pr * pr + pi * pi
        qr, qi = pr / den, -pi / den  # 1 / pivot
        for i in range(k + 1, n):
            fr = Ar[i][k] * qr - Ai[i][k] * qi
            fi = Ar[i][k] * qi + Ai[i][k] * qr
            for j in range(k + 1, n):
                Ar[i][j] = Ar[i][j] - (fr * Ar[k][j] - fi * Ai[k][j])
                Ai[i][j] = Ai[i][j] - (fr * Ai[k][j] + fi * Ar[k][j])
            yr[i], yi[i] = yr[i] - (fr * yr[k] - fi * yi[k]), yi[i] - (fr * yi[k] + fi * yr[k])
    xr = [None] * n
    xi = [None] * n
    for k in reversed(range(n)):
        sr, si = yr[k], yi[k]
        for j in range(k + 1, n):
            sr = sr - (Ar[k][j] * xr[j] - Ai[k][j] * xi[j])
            si = si - (Ar[k][j] * xi[j] + Ai[k][j] * xr[j])
        pr, pi = Ar[k][k], Ai[k][k]
        den = pr * pr + pi * pi
        xr[k] = (sr * pr + si * pi) / den
        xi[k] = (si * pr - sr * pi) / den
    return ca.vertcat(*xr), ca.vertcat(*xi)


def frf_symbolic(M, C, K, w, b, output="receptance", Kh=None):
    """Real and imaginary parts of the FRF of every DOF at circular frequency w.

    M, C, K are SX matrices, b the load vector (-M 1 for ground input, e_k for
    a force), output as in :mod:`nlp.frf.reference`; Kh an optional hysteretic
    (frequency-independent) damping matrix, Z = K - w^2 M + j (w C + Kh).
    Returns (Hr, Hi), SX column vectors.
    """
    n = M.shape[0]
    Zi = w * C if Kh is None else w * C + Kh
    hr, hi = complex_solve(K - w**2 * M, Zi, b, ca.SX.zeros(n))
    p = POWER[output]
    if p == 1:  # jw H
        hr, hi = -w * hi, w * hr
    elif p == 2:  # -w^2 H
        hr, hi = -(w**2) * hr, -(w**2) * hi
    if output == "absolute_accelerance":
        hr = hr + 1
    return hr, hi
