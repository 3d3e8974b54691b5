"""Structural model: nominal matrices and their influence matrices (Eqns 23-24).

K = K0 + sum_r alpha_r K0_r,   M = M0 + sum_r beta_r M0_r

alpha and beta are relative changes of physical parameters (a story stiffness,
a floor mass): alpha_r = 0.1 means that parameter is 10 % above nominal. Each
influence matrix K0_r (M0_r) is the nominal contribution of parameter r, so
the updated physical value is nominal_r * (1 + alpha_r).
"""

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

__all__ = ["StructuralModel", "shear_frame", "shear_stiffness"]


@dataclass(frozen=True)
class StructuralModel:
    """Nominal matrices, influence matrices and the names of their parameters.

    Attributes
    ----------
    M0, K0 : (n, n) ndarray or scipy.sparse matrix
        Nominal mass [kg] and stiffness [N/m] matrices.
    M_infl, K_infl : tuple of (n, n) ndarray or scipy.sparse matrix
        Influence matrices M0_r and K0_r of Eqns 23-24.
    beta_names, alpha_names : tuple of str
        One name per influence matrix (e.g. ``m1``, ``k1``).
    beta_nominal, alpha_nominal : (n_beta,), (n_alpha,) ndarray
        Nominal physical value of each parameter (kg, N/m), for reporting
        ``nominal * (1 + relative change)``; 1.0 where there is none.
    dof_names : tuple of str
        Name of each degree of freedom (``floor1``...).
    dofs : tuple of (int, int)
        Node-to-DOF map of imported models (:mod:`nlp.io.importers`): the node tag
        and 1-based DOF number (OpenSees numbering) of every row; empty for
        shear frames, whose rows are floors.
    ndm : int, optional
        Spatial dimension of an imported model (2 or 3), for DOF names.
    node_coords : tuple of (int, tuple of float)
        Coordinates [m] of the nodes of an imported model that knows them (OpenSees),
        for locations in model terms (:mod:`nlp.diagnosis.locations`); else empty.

    The matrices may be ``scipy.sparse`` (imported models); :meth:`dense`
    gives a copy with ndarrays.
    """

    M0: np.ndarray
    K0: np.ndarray
    M_infl: tuple
    K_infl: tuple
    beta_names: tuple
    alpha_names: tuple
    beta_nominal: np.ndarray
    alpha_nominal: np.ndarray
    dof_names: tuple = field(default=())
    dofs: tuple = field(default=())
    ndm: int = None
    node_coords: tuple = field(default=())

    @property
    def n(self):
        """Number of degrees of freedom."""
        return self.M0.shape[0]

    @property
    def is_sparse(self):
        """True when the matrices are scipy.sparse."""
        return sp.issparse(self.K0)

    def dense(self):
        """A copy whose matrices are dense ndarrays."""
        if not self.is_sparse:
            return self

        def d(A):
            return A.toarray() if sp.issparse(A) else np.asarray(A)

        return replace(self, M0=d(self.M0), K0=d(self.K0), M_infl=tuple(d(A) for A in self.M_infl),
                       K_infl=tuple(d(A) for A in self.K_infl))

    def matrices(self, alpha, beta):
        """Return (M, K) for relative changes alpha, beta (Eqns 23-24).

        Works with numpy arrays and with CasADi symbols.
        """
        M = self.M0 + sum(b * Mr for b, Mr in zip(_items(beta), self.M_infl))
        K = self.K0 + sum(a * Kr for a, Kr in zip(_items(alpha), self.K_infl))
        return M, K


def _items(v):
    n = v.shape[0] if hasattr(v, "shape") else len(v)
    return [v[i] for i in range(n)]


def shear_stiffness(k):
    """Stiffness matrix of a shear frame with story stiffnesses k [N/m].

    Story 1 joins the ground and floor 1; story r joins floors r-1 and r.
    """
    k = np.asarray(k, dtype=float)
    n = k.size
    K = np.zeros((n, n))
    for r in range(n):
        K[r, r] += k[r]
        if r > 0:
            K[r - 1, r - 1] += k[r]
            K[r - 1, r] -= k[r]
            K[r, r - 1] -= k[r]
    return K


def shear_frame(masses, stiffnesses, sparse=None):
    """Shear-frame model: one mass parameter per floor, one stiffness per story.

    Parameters
    ----------
    masses : array_like, (n,)
        Nominal floor masses [kg], floor 1 first.
    stiffnesses : array_like, (n,)
        Nominal story stiffnesses [N/m]; story 1 is between ground and floor 1.
    sparse : bool, optional
        Store every matrix as scipy.sparse.csc_matrix (default: when n > 400,
        where 2n dense influence matrices would not fit in memory).
    """
    m = np.asarray(masses, dtype=float)
    k = np.asarray(stiffnesses, dtype=float)
    n = m.size
    if sparse is None:
        sparse = n > 400
    if sparse:
        return _sparse_shear_frame(m, k)
    eye = np.eye(n)
    return StructuralModel(
        M0=np.diag(m),
        K0=shear_stiffness(k),
        M_infl=tuple(np.diag(m[r] * eye[r]) for r in range(n)),
        K_infl=tuple(shear_stiffness(k[r] * eye[r]) for r in range(n)),
        beta_names=tuple(f"m{r + 1}" for r in range(n)),
        alpha_names=tuple(f"k{r + 1}" for r in range(n)),
        beta_nominal=m.copy(),
        alpha_nominal=k.copy(),
        dof_names=tuple(f"floor{r + 1}" for r in range(n)),
    )


def _sparse_shear_frame(m, k):
    """shear_frame with scipy.sparse CSC matrices (story r: 2 x 2 block on floors r-1, r)."""
    n = m.size

    def story(r, kr):
        if r == 0:
            return sp.csc_matrix(([kr], ([0], [0])), shape=(n, n))
        i = [r - 1, r - 1, r, r]
        j = [r - 1, r, r - 1, r]
        return sp.csc_matrix(([kr, -kr, -kr, kr], (i, j)), shape=(n, n))

    K_infl = tuple(story(r, k[r]) for r in range(n))
    return StructuralModel(
        M0=sp.diags(m, format="csc"),
        K0=sp.csc_matrix(sum(K_infl)),
        M_infl=tuple(sp.csc_matrix(([m[r]], ([r], [r])), shape=(n, n)) for r in range(n)),
        K_infl=K_infl,
        beta_names=tuple(f"m{r + 1}" for r in range(n)),
        alpha_names=tuple(f"k{r + 1}" for r in range(n)),
        beta_nominal=m.copy(),
        alpha_nominal=k.copy(),
        dof_names=tuple(f"floor{r + 1}" for r in range(n)),
    )
