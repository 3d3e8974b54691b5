"""Damping models: general SPD (Cholesky), Rayleigh, modal, general in a modal basis, dashpots.

Each model maps a parameter vector theta to a damping matrix C [N s/m] and
works on numpy arrays and CasADi symbols alike, so the same code builds the
NLP and evaluates results. Each also states its structure,

    C = cM M + cK K + U S U^T + sum_j g_j D_j,

with U (n, m) and D_j fixed and (cM, cK, S, g) functions of theta
(:meth:`structure`), which the sparse FRF backend uses: C then costs no more
than M and K plus a rank-m term, whatever n is.

General viscous damping (Eqn 25f): C = S Lt Lt^T S with Lt lower triangular,
diag(Lt) = exp(theta_diag) and S = diag(sqrt(diag(C0))). Every entry of Lt is
a variable; the exponential keeps the diagonal positive, so C is symmetric
positive definite for every theta, and scaling by the initial C0 makes
theta = O(1) (the initial point has Lt = chol(S^-1 C0 S^-1)).
"""

from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

__all__ = [
    "GeneralDamping",
    "ModalGeneralDamping",
    "DashpotDamping",
    "RayleighDamping",
    "ModalDamping",
    "rayleigh_from_ratios",
    "modal_properties_undamped",
]


def _is_symbolic(x):
    return isinstance(x, (ca.SX, ca.MX))


def _unit_lower_factor(theta, n):
    """Lower-triangular Lt: diagonal exp(theta[:n]), strict lower triangle theta[n:] row by row."""
    sym = _is_symbolic(theta)
    Lt = type(theta).zeros(n, n) if sym else np.zeros((n, n))
    exp = ca.exp if sym else np.exp
    for i in range(n):
        Lt[i, i] = exp(theta[i])
    k = n
    for i in range(n):
        for j in range(i):
            Lt[i, j] = theta[k]
            k += 1
    return Lt


@dataclass(frozen=True)
class GeneralDamping:
    """General SPD damping C = S Lt Lt^T S (Eqn 25f), scaled to C0.

    Parameters are ordered: log-diagonal of Lt (n), then the strict lower
    triangle of Lt row by row, named ``L[i,j]`` with 1-based floors.
    """

    C0: np.ndarray

    @property
    def n(self):
        return self.C0.shape[0]

    @property
    def scale(self):
        return np.sqrt(np.diag(self.C0))

    @property
    def names(self):
        n = self.n
        diag = [f"L[{i + 1},{i + 1}]" for i in range(n)]
        off = [f"L[{i + 1},{j + 1}]" for i in range(n) for j in range(i)]
        return tuple(diag + off)

    def initial(self):
        """theta that reproduces C0 exactly."""
        s = self.scale
        Lt = np.linalg.cholesky(self.C0 / np.outer(s, s))
        n = self.n
        diag = np.log(np.diag(Lt))
        off = [Lt[i, j] for i in range(n) for j in range(i)]
        return np.concatenate([diag, off])

    def default_bounds(self, diag_factor=30.0, offdiag=3.0):
        """Lt diagonal within C0's times/divided by diag_factor; |off| <= offdiag."""
        n = self.n
        m = n * (n - 1) // 2
        lo = np.concatenate([np.full(n, -np.log(diag_factor)), np.full(m, -offdiag)])
        return lo, -lo

    def lower_factor(self, theta):
        """Lt as a CasADi or numpy matrix."""
        return _unit_lower_factor(theta, self.n)

    def matrix(self, theta, M=None, K=None):
        """C(theta) [N s/m]; M and K are not used."""
        s = self.scale
        Lt = self.lower_factor(theta)
        if _is_symbolic(theta):
            SL = ca.diag(ca.DM(s)) @ Lt
            return SL @ SL.T
        SL = s[:, None] * Lt
        return SL @ SL.T

    def scale_direction(self, theta):
        """d theta / d ln(c) when C is multiplied by c (for the null-space check)."""
        n = self.n
        return np.concatenate([np.full(n, 0.5), 0.5 * np.asarray(theta[n:])])

    @property
    def U(self):
        return np.diag(self.scale)

    dashpots = ()

    def structure(self, theta):
        """(cM, cK, S, g): C = U S U^T with U = diag(s), S = Lt Lt^T."""
        Lt = self.lower_factor(theta)
        return 0, 0, Lt @ Lt.T, []


@dataclass(frozen=True)
class RayleighDamping:
    """Rayleigh damping C = a0 M + a1 K, theta = (a0 / a0_ref, a1 / a1_ref)."""

    a0_ref: float
    a1_ref: float

    names = ("a0", "a1")

    def initial(self):
        return np.array([1.0, 1.0])

    def default_bounds(self, factor=30.0):
        return np.array([0.0, 0.0]), np.array([factor, factor])

    def matrix(self, theta, M, K):
        return self.a0_ref * theta[0] * M + self.a1_ref * theta[1] * K

    def scale_direction(self, theta):
        # C scales with M and K already.
        return np.zeros(2)

    U = None
    dashpots = ()

    def structure(self, theta):
        """(cM, cK, S, g) = (a0, a1, none, none)."""
        return self.a0_ref * theta[0], self.a1_ref * theta[1], None, []


@dataclass(frozen=True)
class ModalDamping:
    """Modal damping: C = M0 Phi0 diag(2 zeta_i omega_i) Phi0^T M0.

    Phi0 (mass-normalised) and omega_i are the undamped modes of the nominal
    model; theta are the ratios zeta_i. The ratios therefore refer to the
    nominal modes: exact when masses and stiffnesses change uniformly, an
    approximation otherwise (use the general model for large changes).
    """

    M0: np.ndarray
    K0: np.ndarray
    zeta0: np.ndarray

    @property
    def names(self):
        return tuple(f"zeta{i + 1}" for i in range(self.M0.shape[0]))

    def initial(self):
        return np.asarray(self.zeta0, dtype=float)

    def default_bounds(self):
        n = self.M0.shape[0]
        return np.full(n, 1e-5), np.full(n, 0.5)

    def _basis(self):
        omega, Phi = modal_properties_undamped(self.M0, self.K0)
        return omega, self.M0 @ Phi

    def matrix(self, theta, M=None, K=None):
        omega, MPhi = self._basis()
        n = omega.size
        if _is_symbolic(theta):
            C = 0
            for i in range(n):
                v = ca.DM(MPhi[:, i])
                C = C + 2 * theta[i] * omega[i] * (v @ v.T)
            return C
        return MPhi @ np.diag(2 * np.asarray(theta) * omega) @ MPhi.T

    def scale_direction(self, theta):
        return np.asarray(theta, dtype=float)

    @property
    def U(self):
        return self._basis()[1]

    dashpots = ()

    def structure(self, theta):
        """(cM, cK, S, g): C = U S U^T with U = M0 Phi0, S = diag(2 zeta_i omega_i)."""
        omega = self._basis()[0]
        sym = _is_symbolic(theta)
        d = [2 * theta[i] * omega[i] for i in range(omega.size)]
        return 0, 0, (ca.diag(ca.vertcat(*d)) if sym else np.diag(d)), []


@dataclass(frozen=True, eq=False)
class ModalGeneralDamping:
    """General SPD damping on the band's modes plus a proportional remainder.

    C = M0 Phi (L L^T) Phi^T M0 + C_rest, where Phi (n, m) are the nominal
    mass-normalised modes of the band, L is lower triangular with a positive
    diagonal, and C_rest = a0 M + a1 K with its band-mode part removed
    (C_rest Phi = 0 at the nominal model), so the band's modal damping matrix is
    exactly L L^T: Phi^T C Phi = L L^T (the paper's general damping, Eqn 25f, in
    m (m + 1) / 2 variables at any n). Parameters: ln L_ii (as ``L[i,i]``)
    then the strict lower triangle, scaled by sqrt(2 zeta0_i omega_i) so they
    are O(1); the remainder (a0, a1) is fixed (outside the band it is barely
    seen by the data).

    Parameters
    ----------
    Phi : (n, m) ndarray
        Mass-normalised nominal modes of the band.
    omega : (m,) ndarray
        Their circular frequencies [rad/s].
    MPhi : (n, m) ndarray
        M0 Phi.
    zeta0 : (m,) ndarray
        Initial modal damping ratios.
    a0, a1 : float
        Proportional remainder coefficients [1/s], [s].
    """

    Phi: np.ndarray
    omega: np.ndarray
    MPhi: np.ndarray
    zeta0: np.ndarray
    a0: float = 0.0
    a1: float = 0.0
    modes: tuple = ()

    @classmethod
    def from_model(cls, M0, K0, modes, zeta0, a0=0.0, a1=0.0):
        """Nominal modes ``modes`` (1-based) of (M0, K0), dense or scipy.sparse."""
        omega, Phi = band_modes(M0, K0, max(modes))
        idx = np.asarray(modes) - 1
        Phi, omega = Phi[:, idx], omega[idx]
        return cls(Phi=Phi, omega=omega, MPhi=np.asarray(M0 @ Phi), zeta0=np.asarray(zeta0, float),
                    a0=float(a0), a1=float(a1), modes=tuple(int(i) for i in modes))

    @property
    def m(self):
        return self.omega.size

    @property
    def scale(self):
        return np.sqrt(2 * self.zeta0 * self.omega)

    @property
    def names(self):
        lab = self.modes or tuple(range(1, self.m + 1))
        diag = [f"L[{i},{i}]" for i in lab]
        off = [f"L[{lab[i]},{lab[j]}]" for i in range(self.m) for j in range(i)]
        return tuple(diag + off)

    def initial(self):
        """theta giving modal damping ratios zeta0 and no modal coupling."""
        return np.concatenate([np.zeros(self.m), np.zeros(self.m * (self.m - 1) // 2)])

    def default_bounds(self, diag_factor=30.0, offdiag=3.0):
        """L_ii within sqrt(diag_factor) of the initial; |L_ij| <= offdiag (scaled)."""
        m = self.m
        k = m * (m - 1) // 2
        lo = np.concatenate([np.full(m, -0.5 * np.log(diag_factor)), np.full(k, -offdiag)])
        return lo, -lo

    def lower_factor(self, theta):
        """L = diag(s) Lt with Lt unit-scaled (exp diagonal), numpy or CasADi."""
        Lt = _unit_lower_factor(theta, self.m)
        s = self.scale
        return (ca.diag(ca.DM(s)) @ Lt) if _is_symbolic(theta) else s[:, None] * Lt

    @property
    def U(self):
        return self.MPhi

    dashpots = ()

    def structure(self, theta):
        """(cM, cK, S, g): S = L L^T - a0 I - a1 diag(omega^2) cancels the remainder's band part."""
        L = self.lower_factor(theta)
        rest = np.diag(self.a0 + self.a1 * self.omega ** 2)
        return self.a0, self.a1, L @ L.T - (ca.DM(rest) if _is_symbolic(theta) else rest), []

    def matrix(self, theta, M, K):
        """C(theta) = a0 M + a1 K + M0 Phi S Phi^T M0 [N s/m]."""
        return structure_matrix(self, theta, M, K)

    def modal_matrix(self, theta):
        """Phi^T C Phi = L L^T, the band's modal damping matrix [1/s]."""
        L = self.lower_factor(theta)
        return L @ L.T

    def scale_direction(self, theta):
        m = self.m
        return np.concatenate([np.full(m, 0.5), 0.5 * np.asarray(theta[m:])])


@dataclass(frozen=True)
class DashpotDamping:
    """Element dashpots: C = a0 theta_0 M + sum_j a1 theta_j K0_j.

    Each stiffness group K0_j (a story, an element group) gets a dashpot of
    its own, proportional to its stiffness (c_j = a1 theta_j k_j); theta = 1
    is the Rayleigh model (a0, a1) and each theta_j rescales one group's
    damping. Mass-proportional part a0 theta_0 M for the base.
    """

    a0_ref: float
    a1_ref: float
    K_groups: tuple
    group_names: tuple

    @property
    def names(self):
        return ("a0",) + tuple(f"c_{g}" for g in self.group_names)

    def initial(self):
        return np.ones(1 + len(self.K_groups))

    def default_bounds(self, factor=300.0):
        # a concentrated damper of s times its story's share of the structure's damping
        # ratio is c = s 2 zeta sqrt(k m) = s (w_1 + w_n) / w_story times the Rayleigh
        # dashpot a1 k; w_n / w_1 of an n-storey shear frame reaches about 4 n / pi, so
        # 30 (the general factor) can cap a damper of s = 4 on five storeys
        k = 1 + len(self.K_groups)
        return np.zeros(k), np.full(k, factor)

    U = None

    @property
    def dashpots(self):
        return tuple(self.a1_ref * Kj for Kj in self.K_groups)

    def structure(self, theta):
        return self.a0_ref * theta[0], 0, None, [theta[j + 1] for j in range(len(self.K_groups))]

    def matrix(self, theta, M, K=None):
        C = self.a0_ref * theta[0] * M
        for j, D in enumerate(self.dashpots):
            C = C + theta[j + 1] * (ca.DM(_dense(D)) if _is_symbolic(theta) else D)
        return C

    def scale_direction(self, theta):
        return np.zeros(1 + len(self.K_groups))


def structure_matrix(damping, theta, M, K):
    """C = cM M + cK K + U S U^T + sum_j g_j D_j from ``damping.structure(theta)``."""
    cM, cK, S, g = damping.structure(theta)
    sym = _is_symbolic(theta) or _is_symbolic(M)
    C = cM * M + cK * K
    if S is not None:
        U = damping.U
        C = C + (ca.DM(U) @ S @ ca.DM(U).T if sym else U @ S @ U.T)
    for gj, D in zip(g, damping.dashpots):
        C = C + gj * (ca.DM(_dense(D)) if sym else D)
    return C


def _dense(A):
    return A.toarray() if hasattr(A, "toarray") else np.asarray(A)


def band_modes(M0, K0, count):
    """The lowest ``count`` undamped modes (omega [rad/s], mass-normalised Phi (n, count)).

    Dense eigh for small n; shift-invert Lanczos (scipy.sparse.linalg.eigsh)
    for large sparse models.
    """
    n = M0.shape[0]
    if n <= 400 or count >= n - 1:
        lam, Phi = sla.eigh(_dense(K0), _dense(M0), subset_by_index=[0, min(count, n) - 1])
    else:
        lam, Phi = spla.eigsh(K0.tocsc() if hasattr(K0, "tocsc") else K0, k=count,
                              M=M0, sigma=0.0, which="LM")
        order = np.argsort(lam)
        lam, Phi = lam[order], Phi[:, order]
        Phi = Phi / np.sqrt(np.einsum("ij,ij->j", Phi, np.asarray(M0 @ Phi)))
    return np.sqrt(np.abs(lam)), Phi


def modal_properties_undamped(M, K):
    """Undamped natural circular frequencies [rad/s] and mass-normalised modes."""
    lam, Phi = sla.eigh(K, M)
    return np.sqrt(np.abs(lam)), Phi


def rayleigh_from_ratios(M, K, zeta, modes=(1, None)):
    """Rayleigh coefficients (a0, a1) giving ratio zeta at two modes (1-based).

    zeta_i = a0 / (2 omega_i) + a1 omega_i / 2. ``modes=(1, None)`` means the
    first and the last mode.
    """
    omega, _ = modal_properties_undamped(M, K)
    i = modes[0] - 1
    j = (modes[1] - 1) if modes[1] is not None else omega.size - 1
    wi, wj = omega[i], omega[j]
    a0 = 2 * zeta * wi * wj / (wi + wj)
    a1 = 2 * zeta / (wi + wj)
    return a0, a1
