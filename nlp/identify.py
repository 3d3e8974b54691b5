"""What the data can and cannot fix: scale null space, Jacobian SVD, errors.

Base-excitation FRFs H_rg = -(K - w^2 M + jwC)^-1 M 1 are unchanged when M, C
and K are all multiplied by one factor, so from them alone masses and
stiffnesses cannot all be updated: the problem needs an anchor (a weighed
mass held fixed, or the total mass). Force-input FRFs have no such null space.
"""

import numpy as np

__all__ = ["scale_null_space", "jacobian_report", "standard_errors", "SCALE_EXPLANATION"]

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


def jacobian_report(J, names, rtol=1e-6):
    """Singular values of the column-scaled Jacobian and weak directions.

    Columns are scaled to unit norm so that the singular values compare
    parameter combinations, not units. A direction with sigma / sigma_max <
    rtol is reported as not identifiable, with the parameters that dominate it.
    """
    norms = np.linalg.norm(J, axis=0)
    Js = J / np.where(norms > 0, norms, 1.0)
    _, sv, Vt = np.linalg.svd(Js, full_matrices=False)
    ratio = sv / sv[0] if sv[0] > 0 else np.zeros_like(sv)
    weak = []
    for k in np.nonzero(ratio < rtol)[0]:
        v = Vt[k]
        top = np.argsort(-np.abs(v))[:4]
        weak.append({"sigma_ratio": float(ratio[k]),
                     "combination": {names[i]: round(float(v[i]), 4) for i in top if abs(v[i]) > 0.05}})
    for i in np.nonzero(norms == 0)[0]:
        weak.append({"sigma_ratio": 0.0, "combination": {names[i]: 1.0},
                     "note": "the residuals do not depend on this parameter"})
    return {"singular_values": sv.tolist(), "condition_number": float(ratio[0] / ratio[-1])
            if ratio[-1] > 0 else float("inf"), "weak_directions": weak}


def standard_errors(J, r, n_used):
    """Gauss-Newton covariance of z at the optimum: s^2 (J^T J)^-1.

    s^2 = r^T r / (n_used - n_z) estimates the residual noise variance. Returns
    (cov, s2, dof). Use with care when parameters sit on their bounds.
    """
    n_z = J.shape[1]
    dof = max(int(n_used) - n_z, 1)
    s2 = float(r @ r) / dof
    cov = s2 * np.linalg.pinv(J.T @ J)
    return cov, s2, dof
