"""Frequency response functions in numpy: the reference implementation.

Conventions
-----------
Y(w) = H(w) X(w) with the e^{-jwt} forward Fourier transform, so a single
degree of freedom has receptance 1 / (k - w^2 m + j w c).

Excitation
    ``"ground"``: ground acceleration a_g; the response q is displacement
    relative to the ground and the equivalent load is F = -M 1 a_g (Eqn 16).
    ``"force"``: a force [N] at one degree of freedom e (Eqn 15).
Output (Eqns 18-19)
    ``"receptance"`` H, ``"mobility"`` jwH, ``"accelerance"`` -w^2 H, and for
    ground input ``"absolute_accelerance"`` -w^2 H + 1 (what an accelerometer
    on a shake-table structure reads, relative response plus ground motion).

Three independent evaluations agree to round-off: the modal sum over the
complex modes of the state-space system (Eqns 5, 15, 17), a direct solve of
(jwA + B) x = P (Eqns 2-4), and the dynamic stiffness (K - w^2 M + jwC).
"""

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse import csgraph

from nlp.frf.forms import OUTPUTS, POWER

__all__ = [
    "OUTPUTS",
    "EXCITATIONS",
    "load_vector",
    "output_factor",
    "state_space_matrices",
    "complex_modes",
    "frf_modal",
    "frf_state_space",
    "frf_dynamic_stiffness",
    "modal_parameters",
    "channel_frfs",
    "BASE_DOF",
]

EXCITATIONS = ("ground", "force")


def load_vector(M, excitation="ground", force_dof=None, r=None):
    """Load vector b of Mq'' + Cq' + Kq = b u (u = a_g or the force).

    r : (n,) influence vector of the ground motion (default all ones): b = -M r.
    """
    n = M.shape[0]
    if excitation == "ground":
        return -(M @ (np.ones(n) if r is None else np.asarray(r, float)))
    if excitation == "force":
        b = np.zeros(n)
        b[force_dof] = 1.0
        return b
    raise ValueError(f"excitation must be one of {EXCITATIONS}, got {excitation!r}")


def output_factor(omega, output):
    """(jw)^p for receptance (p=0), mobility (1), accelerance (2) (Eqns 18-19)."""
    if output not in POWER:
        raise ValueError(f"output must be one of {OUTPUTS}, got {output!r}")
    return (1j * np.asarray(omega)) ** POWER[output]


def _apply_output(Hq, omega, output):
    H = Hq * output_factor(omega, output)
    if output == "absolute_accelerance":
        H = H + 1.0
    return H


def state_space_matrices(M, C, K):
    """A and B of Eqn 4: A = [[C, M], [M, 0]], B = [[K, 0], [0, -M]]."""
    n = M.shape[0]
    Z = np.zeros((n, n))
    A = np.block([[C, M], [M, Z]])
    B = np.block([[K, Z], [Z, -M]])
    return A, B


def complex_modes(M, C, K):
    """Complex eigenvalues s_i and A-normalised eigenvectors psi_i (Eqns 5-6).

    Returns s (2n,) and Psi (2n, 2n) with Psi^T A Psi = I and
    Psi^T B Psi = -diag(s) (plain transpose, not conjugate).
    """
    A, B = state_space_matrices(M, C, K)
    s, Psi = sla.eig(-B, A)
    norm = np.sqrt(np.einsum("ji,jk,ki->i", Psi, A, Psi))
    return s, Psi / norm


def frf_modal(M, C, K, omega, excitation="ground", force_dof=None, output="receptance"):
    """FRFs of every DOF by the modal sum (Eqns 15 and 17).

    Returns (n, n_omega) complex; for ground input H_rg = sum_i
    -phi_ri (phi_i^T M 1) / (jw - s_i), which for lumped masses is Eqn 17.
    """
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    n = M.shape[0]
    s, Psi = complex_modes(M, C, K)
    Phi = Psi[:n]
    b = load_vector(M, excitation, force_dof)
    participation = Phi.T @ b  # phi_i^T b
    Hq = (Phi * participation) @ (1.0 / (1j * omega[None, :] - s[:, None]))
    return _apply_output(Hq, omega, output)


def frf_state_space(M, C, K, omega, excitation="ground", force_dof=None, output="receptance"):
    """FRFs by solving (jwA + B) x = P at each frequency (Eqns 2-4)."""
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    n = M.shape[0]
    A, B = state_space_matrices(M, C, K)
    P = np.concatenate([load_vector(M, excitation, force_dof), np.zeros(n)])
    Hq = np.empty((n, omega.size), dtype=complex)
    for k, w in enumerate(omega):
        Hq[:, k] = np.linalg.solve(1j * w * A + B, P)[:n]
    return _apply_output(Hq, omega, output)


def frf_dynamic_stiffness(M, C, K, omega, excitation="ground", force_dof=None,
                          output="receptance", r=None, dofs=None):
    """FRFs from the dynamic stiffness: (K - w^2 M + jwC) q = b (r: ground influence).

    ``dofs``: only these rows, in this order (default: every DOF)."""
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    b = load_vector(M, excitation, force_dof, r)
    if M.shape[0] > LARGE_N:
        ab = _rayleigh_coefficients(M, C, K)
        if ab is None:
            Hq = _solve_sparse(M, C, K, omega, b)
            Hq = Hq if dofs is None else Hq[np.asarray(dofs)]
        else:
            Hq = _solve_proportional(M, K, ab, omega, b, dofs)
        return _apply_output(Hq, omega, output)
    Z = K[None] - omega[:, None, None] ** 2 * M[None] + 1j * omega[:, None, None] * C[None]
    Hq = np.linalg.solve(Z, np.broadcast_to(b, (omega.size, b.size))[..., None])[..., 0].T
    return _apply_output(Hq if dofs is None else Hq[np.asarray(dofs)], omega, output)


# Above this many DOFs the stacked dense solve (N n^2 complex numbers) gives way to one
# sparse factorisation per frequency, and modal_parameters to the lowest N_MODES_LARGE modes.
LARGE_N = 400
N_MODES_LARGE = 30


def _solve_sparse(M, C, K, omega, b):
    """q(w) of (K - w^2 M + jwC) q = b, one sparse LU per frequency: reverse Cuthill-McKee
    ordering and no pivoting (-jZ has the positive definite Hermitian part wC)."""
    Ms, Cs, Ks = (sp.csc_matrix(A) for A in (M, C, K))
    pattern = sp.csr_matrix(abs(Ms) + abs(Cs) + abs(Ks))
    p = csgraph.reverse_cuthill_mckee(pattern, symmetric_mode=True)
    Mp, Cp, Kp = (A[p][:, p].tocsc() for A in (Ms, Cs, Ks))
    Hq = np.empty((b.size, omega.size), complex)
    bp = np.asarray(b, complex)[p]
    for k, w in enumerate(omega):
        lu = spla.splu((Kp - w**2 * Mp + 1j * w * Cp).tocsc(), permc_spec="NATURAL",
                       diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        Hq[p, k] = lu.solve(bp)
    return Hq


def _rayleigh_coefficients(M, C, K, rtol=1e-12):
    """(a0, a1) when C = a0 M + a1 K to round-off (least squares on the entries), else None."""
    Ms, Cs, Ks = (sp.csr_matrix(A) for A in (M, C, K))
    pat = (abs(Ms) + abs(Cs) + abs(Ks)).tocoo()
    r, c = pat.row, pat.col
    A = np.column_stack([np.asarray(Ms[r, c]).ravel(), np.asarray(Ks[r, c]).ravel()])
    y = np.asarray(Cs[r, c]).ravel()
    if not np.any(y):
        return 0.0, 0.0
    ab, *_ = np.linalg.lstsq(A, y, rcond=None)
    return tuple(ab) if np.linalg.norm(A @ ab - y) <= rtol * np.linalg.norm(y) else None


_MODES_CACHE = {}


def _solve_proportional(M, K, ab, omega, b, dofs=None):
    """q(w) for C = a0 M + a1 K by the sum over ALL undamped modes (exact for this damping):
    q = Phi diag(1 / (lam_r - w^2 + jw (a0 + a1 lam_r))) Phi^T b. One dense eigh (divide and
    conquer, 3 s at 2,100 DOFs) replaces a sparse LU per frequency (0.1 s each); cached per
    (M, K) for the two models a run compares (initial and updated), since the result files
    evaluate each on several grids. ``dofs``: only these rows of q."""
    Md, Kd = (A.toarray() if sp.issparse(A) else np.asarray(A, float) for A in (M, K))
    key = (hash(Md.tobytes()), hash(Kd.tobytes()))
    if key not in _MODES_CACHE:
        while len(_MODES_CACHE) >= 2:  # n^2 floats each
            _MODES_CACHE.pop(next(iter(_MODES_CACHE)))
        _MODES_CACHE[key] = sla.eigh(Kd, Md, driver="gvd")
    lam, Phi = _MODES_CACHE[key]
    a0, a1 = ab
    g = Phi.T @ np.asarray(b, float)
    den = lam[:, None] - omega[None, :] ** 2 + 1j * omega[None, :] * (a0 + a1 * lam[:, None])
    X = g[:, None] / den
    rows = Phi if dofs is None else Phi[np.asarray(dofs)]
    return rows @ X.real + 1j * (rows @ X.imag)  # two real products, not one complex one


def _lowest_complex_modes(M, C, K, k):
    """The k complex pairs of smallest |s| of s A psi = -B psi (Eqn 5), by Arnoldi on
    -B^-1 A (largest 1/|s|): only K is factorised, once, sparse."""
    n = M.shape[0]
    Ms, Cs, Ks = (sp.csc_matrix(A) for A in (M, C, K))
    lk = spla.splu(Ks)

    def op(x):  # -B^-1 A x = [-K^-1 (C x1 + M x2); x1]
        x1, x2 = x[:n], x[n:]
        y = Cs @ x1 + Ms @ x2
        return np.concatenate([-(lk.solve(y.real) + 1j * lk.solve(y.imag)), x1])

    L = spla.LinearOperator((2 * n, 2 * n), matvec=op, dtype=complex)
    mu, V = spla.eigs(L, k=min(2 * k, 2 * n - 2), which="LM", tol=1e-10)
    return 1.0 / mu, V


def modal_parameters(M, C, K):
    """Natural frequencies [Hz] and damping ratios from the complex eigenvalues.

    For each complex pair s = -zeta w +- j w sqrt(1 - zeta^2): f = |s| / 2pi,
    zeta = -Re(s) / |s|. Sorted by frequency; overdamped (real) roots are
    dropped. Also returns the complex mode shapes phi (n, n_modes). Above LARGE_N
    DOFs only the N_MODES_LARGE lowest modes (sparse Arnoldi).
    """
    n = M.shape[0]
    if n > LARGE_N:
        s, Psi = _lowest_complex_modes(M, C, K, N_MODES_LARGE)
    else:
        s, Psi = complex_modes(M, C, K)
    keep = s.imag > 0
    s, Phi = s[keep], Psi[:n, keep]
    order = np.argsort(np.abs(s))
    s, Phi = s[order], Phi[:, order]
    return np.abs(s) / (2 * np.pi), -s.real / np.abs(s), Phi


BASE_DOF = -1   # Channel.dof of a sensor on the base (floor 0)


def channel_frfs(M, C, K, omega, channels, excitation="ground", force_dof=None, r=None):
    """FRF of each channel (objects with ``dof`` and ``output``): (n_ch, N) complex.

    r : ground influence vector (default all ones). A channel on the base
    (``dof == BASE_DOF``) of this fixed-base model moves with the ground: its
    absolute accelerance is 1 (relative outputs are 0). A channel's own ``force_dof``
    (tests fitted jointly) replaces force_dof.
    """
    out = {}
    rows = []
    dofs = sorted({ch.dof for ch in channels if ch.dof != BASE_DOF})
    at = {d: i for i, d in enumerate(dofs)}
    for ch in channels:
        if ch.dof == BASE_DOF:
            rows.append(np.full(np.size(omega), 1.0 if ch.output == "absolute_accelerance" else 0.0,
                                dtype=complex))
            continue
        p = getattr(ch, "force_dof", None)
        p = force_dof if p is None else p
        if (ch.output, p) not in out:
            out[ch.output, p] = frf_dynamic_stiffness(M, C, K, omega, excitation, p, ch.output, r,
                                                      dofs=dofs)
        rows.append(out[ch.output, p][at[ch.dof]])
    return np.array(rows)
