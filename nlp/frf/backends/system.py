"""The linear system whose FRF the numeric backends evaluate, in sparse form.

    Z(theta, w) q = b(theta),   Z = K - w^2 M + j w C      (Eqns 2-5, Schur form)
    M = M0 + sum_r beta_r M_r,  K = K0 + sum_r alpha_r K_r (Eqns 23-24)
    C = cM M + cK K + U S U^T + sum_j g_j D_j              (nlp.model.damping structure)
    b = b0 + sum_r beta_r b_r   (ground input: b = -M r; force: b = e_f)
    H_c = E[:, c]^T q           (output vectors: unit vectors at sensor DOFs)

Everything except the scalars (alpha, beta, cM, cK, S, g) is fixed, which is
what lets a backend factorise once per frequency and differentiate
analytically. :meth:`LinearSystem.project` gives the same system on a basis
Psi (the reduced backend).
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["LinearSystem"]


def _csc(A):
    return sp.csc_matrix(A, dtype=float)


@dataclass(frozen=True)
class LinearSystem:
    """Fixed matrices and vectors of the FRF system (see module docstring).

    Attributes
    ----------
    M0, K0 : (n, n) scipy.sparse.csc_matrix
        Nominal mass [kg] and stiffness [N/m].
    M_infl, K_infl : tuple of csc_matrix
        Influence matrices (Eqns 23-24).
    U : (n, m) ndarray or None
        Low-rank damping basis.
    dashpots : tuple of csc_matrix
        Fixed dashpot patterns D_j [N s/m].
    b0 : (n,) ndarray
        Load vector at beta = 0 (per unit ground acceleration or force).
    b_infl : tuple of (n,) ndarray
        d b / d beta_r (ground input: -M_r r; empty for a force).
    E : (n, n_ch) ndarray
        Output vectors.
    """

    M0: sp.csc_matrix
    K0: sp.csc_matrix
    M_infl: tuple
    K_infl: tuple
    U: np.ndarray
    dashpots: tuple
    b0: np.ndarray
    b_infl: tuple
    E: np.ndarray

    @property
    def n(self):
        return self.M0.shape[0]

    @classmethod
    def from_model(cls, model, damping, target):
        """The system of a StructuralModel (dense or sparse), a damping model and a Target."""
        n = model.n
        M0 = _csc(model.M0)
        M_infl = tuple(_csc(A) for A in model.M_infl)
        if target.excitation == "ground":
            r = getattr(target, "ground_r", None)
            r = np.ones(n) if r is None else np.asarray(r, float)
            b0 = -(M0 @ r)
            b_infl = tuple(-(A @ r) for A in M_infl)
        else:
            b0 = np.zeros(n)
            b0[target.force_dof] = 1.0
            b_infl = tuple(np.zeros(n) for _ in M_infl)
        E = np.zeros((n, len(target.channels)))
        for c, ch in enumerate(target.channels):
            if ch.dof >= 0:  # a base sensor (BASE_DOF) reads no DOF: 0, +1 when absolute
                E[ch.dof, c] = 1.0
        U = damping.U
        return cls(M0=M0, K0=_csc(model.K0), M_infl=M_infl,
                   K_infl=tuple(_csc(A) for A in model.K_infl),
                   U=None if U is None else np.asarray(U, float),
                   dashpots=tuple(_csc(D) for D in damping.dashpots), b0=b0, b_infl=b_infl, E=E)

    def shifted(self, alpha, beta):
        """The same system re-expressed about theta: M0 -> M(beta), K0 -> K(alpha), b0 -> b(beta).

        Eqns 23-24 at the given relative changes; the influence matrices stay, so
        the result describes the model at theta + (alpha', beta') for any further
        changes. The re-centred reduced basis is computed from it.
        """
        alpha, beta = np.asarray(alpha, float), np.asarray(beta, float)
        K = self.K0 + sum((a * A for a, A in zip(alpha, self.K_infl)), sp.csc_matrix(self.K0.shape))
        M = self.M0 + sum((b * A for b, A in zip(beta, self.M_infl)), sp.csc_matrix(self.M0.shape))
        b0 = self.b0 + sum((b * v for b, v in zip(beta, self.b_infl)), np.zeros(self.n))
        return LinearSystem(M0=_csc(M), K0=_csc(K), M_infl=self.M_infl, K_infl=self.K_infl,
                            U=self.U, dashpots=self.dashpots, b0=b0, b_infl=self.b_infl, E=self.E)

    def padded(self, extra):
        """The same system on ``extra`` more DOFs, appended with no mass, stiffness, load or
        sensor: added physics (:mod:`nlp.frf.backends.terms`) gives them their matrices."""
        if not extra:
            return self
        size = self.n + extra

        def mat(A):
            A = sp.coo_matrix(A)
            return sp.csc_matrix((A.data, (A.row, A.col)), shape=(size, size))

        def rows(x):
            x = np.asarray(x)
            return np.concatenate([x, np.zeros((extra,) + x.shape[1:])])

        return LinearSystem(M0=mat(self.M0), K0=mat(self.K0), M_infl=tuple(mat(A) for A in self.M_infl),
                            K_infl=tuple(mat(A) for A in self.K_infl),
                            U=None if self.U is None else rows(self.U),
                            dashpots=tuple(mat(D) for D in self.dashpots), b0=rows(self.b0),
                            b_infl=tuple(rows(b) for b in self.b_infl), E=rows(self.E))

    def project(self, Psi):
        """The same system on q = Psi eta (Galerkin: every matrix A -> Psi^T A Psi)."""
        Pt = Psi.T

        def mat(A):
            return _csc(Pt @ (A @ Psi))

        return LinearSystem(M0=mat(self.M0), K0=mat(self.K0),
                            M_infl=tuple(mat(A) for A in self.M_infl),
                            K_infl=tuple(mat(A) for A in self.K_infl),
                            U=None if self.U is None else Pt @ self.U,
                            dashpots=tuple(mat(D) for D in self.dashpots),
                            b0=Pt @ self.b0, b_infl=tuple(Pt @ b for b in self.b_infl),
                            E=Pt @ self.E)
