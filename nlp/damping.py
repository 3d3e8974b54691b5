"""Damping models: general SPD (Cholesky), Rayleigh and modal.

Each model maps a parameter vector theta to a damping matrix C [N s/m] and
works on numpy arrays and CasADi symbols alike, so the same code builds the
NLP and evaluates results.

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

__all__ = [
    "GeneralDamping",
    "RayleighDamping",
    "ModalDamping",
    "rayleigh_from_ratios",
    "modal_properties_undamped",
]


def _is_symbolic(x):
    return isinstance(x, (ca.SX, ca.MX))


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
        n = self.n
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
