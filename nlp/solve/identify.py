"""What the data can and cannot fix: scale null space, Jacobian SVD, errors.

Base-excitation FRFs H_rg = -(K - w^2 M + jwC)^-1 M 1 are unchanged when M, C
and K are all multiplied by one factor, so from them alone masses and
stiffnesses cannot all be updated: the problem needs an anchor (a weighed
mass held fixed, or the total mass). Force-input FRFs have no such null space.
"""

import numpy as np

__all__ = ["scale_null_space", "jacobian_report", "standard_errors", "tangent_basis",
           "gauss_newton_covariance", "SCALE_EXPLANATION"]

SCALE_EXPLANATION = (
    "The FRFs are for ground (base) excitation, H_rg = -(K - w^2 M + jwC)^-1 M 1, which do not "
    "change when M, C and K are all multiplied by the same factor. With every mass, stiffness "
    "and damping parameter free, that common scale is not determined by the data: infinitely "
    "many models fit equally well. Anchor the scale in the case file: fix a weighed floor mass "
    "(parameters: fixed: {m1: 5.16}) or give the total mass (parameters: total_mass: 20.4), "
    "or use force-input FRFs, which do fix the scale."
)


def scale_null_space(params, damping, excitation, total_mass=None, tol=1e-9):
    """True when the free parameters can follow a common M-C-K scaling exactly.

    The direction d theta / d ln(s) of scaling M, K, C by s is (1 + alpha),
    (1 + beta) and the damping model's own scale direction; the scale is free
    when that direction lies in the range of the map theta = T z + c.
    """
    if excitation != "ground" or total_mass is not None:
        return False
    theta0 = np.array([p.initial for p in params.params])
    sa, sb, sd = params.slices()
    v = np.concatenate([1 + theta0[sa], 1 + theta0[sb], damping.scale_direction(theta0[sd])])
    T = params.T
    dz, *_ = np.linalg.lstsq(T, v, rcond=None)
    return np.linalg.norm(T @ dz - v) <= tol * np.linalg.norm(v)


def tangent_basis(G, n_z):
    """Orthonormal basis (n_z, n_z - rank G) of the steps dz with G dz = 0.

    G : (n_g, n_z) Jacobian of the equality constraints (the total-mass anchor,
    1^T M 1 = m_total, is linear in beta by Eqn 24). Without constraints: identity.
    """
    G = np.zeros((0, n_z)) if G is None else np.atleast_2d(np.asarray(G, float))
    if G.size == 0:
        return np.eye(n_z)
    _, s, vt = np.linalg.svd(G)
    rank = int(np.sum(s > 1e-12 * s[0])) if s.size and s[0] > 0 else 0
    return vt[rank:].T


def gauss_newton_covariance(J, G=None):
    """(J^T J)^-1 restricted to the constraint surface: N (N^T J^T J N)^-1 N^T.

    An anchored scale (total mass) removes the scale null space of base-excitation
    FRFs only through the constraint; the unconstrained (J^T J)^-1 keeps that null
    direction and its errors are meaningless (thousands of kg on a 5-kg floor).
    """
    N = tangent_basis(G, J.shape[1])
    JN = J @ N
    return N @ np.linalg.pinv(JN.T @ JN) @ N.T


def jacobian_report(J, names, rtol=1e-6, G=None):
    """Singular values of the column-scaled Jacobian and weak directions.

    Columns are scaled to unit norm so that the singular values compare
    parameter combinations, not units. Only steps that keep the equality
    constraints G dz = 0 count (a direction the anchor fixes is not weak). A
    direction with sigma / sigma_max < rtol is reported as not identifiable,
    with the parameters that dominate it.
    """
    norms = np.linalg.norm(J, axis=0)
    D = np.where(norms > 0, norms, 1.0)
    Js = J / D
    Gs = None if G is None else np.atleast_2d(np.asarray(G, float)) / D
    N = tangent_basis(Gs, J.shape[1])
    _, sv, Vt = np.linalg.svd(Js @ N, full_matrices=False)
    ratio = sv / sv[0] if sv.size and sv[0] > 0 else np.zeros_like(sv)
    weak = []
    for k in np.nonzero(ratio < rtol)[0]:
        v = N @ Vt[k]
        v = v / np.linalg.norm(v)
        top = np.argsort(-np.abs(v))[:4]
        weak.append({"sigma_ratio": float(ratio[k]),
                     "combination": {names[i]: round(float(v[i]), 4) for i in top if abs(v[i]) > 0.05}})
    for i in np.nonzero(norms == 0)[0]:
        weak.append({"sigma_ratio": 0.0, "combination": {names[i]: 1.0},
                     "note": "the residuals do not depend on this parameter"})
    return {"singular_values": sv.tolist(), "condition_number": float(ratio[0] / ratio[-1])
            if ratio.size and ratio[-1] > 0 else float("inf"), "weak_directions": weak}


def standard_errors(J, r, n_used, G=None):
    """Gauss-Newton covariance of z at the optimum: s^2 (J^T J)^-1 on the constraint surface.

    G : (n_g, n_z) Jacobian of the equality constraints (None: none). s^2 =
    r^T r / (n_used - n_z + n_g) estimates the residual noise variance. Returns
    (cov, s2, dof). Use with care when parameters sit on their bounds.
    """
    n_z = J.shape[1]
    n_g = 0 if G is None else np.atleast_2d(G).shape[0]
    dof = max(int(n_used) - n_z + n_g, 1)
    s2 = float(r @ r) / dof
    cov = s2 * gauss_newton_covariance(J, G)
    return cov, s2, dof
