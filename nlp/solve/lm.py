"""Levenberg-Marquardt on the directions the data determine: the local solver of the
numeric backends (many parameters).

    minimise f(z) = 1/2 ||r(z)||^2   subject to lo <= z <= hi and G z = h (linear, optional)

At each point, on the variables not held at a bound by the gradient g = J^T r and along
G s = 0, the Gauss-Newton matrix A = J^T J is split by its eigenvalues lambda into the
directions the data determine, lambda > s^2 with s^2 = 2 f / (m - n) the residual
variance, and the rest. Along an undetermined direction v a whole unit step (a 100 %
change of the parameters, whose scaled variables are O(1)) changes the chi-square by
lambda / s^2 < 1: the data cannot tell z from z + v, the standard error along v exceeds
the parameter itself, and the quadratic model's step along v is long and wrong. Steps are
taken on the determined directions B only, damped as Marquardt's,

    (B^T A B + mu B^T D B) y = -B^T g,   s = B y,   D = diag(A),

projected into the box, and accepted when f falls; mu follows the ratio rho of actual to
predicted decrease (Nielsen's rule: Madsen, Nielsen & Tingleff, "Methods for non-linear
least squares problems", 2004, Sec. 3.2). The solve stops when the Gauss-Newton step on
the determined directions would lower 2 f by less than ``LM_STATIONARY`` s^2: the
remaining step is shorter than 0.1 standard error in the metric of the covariance.

Why not IPOPT: it takes the undamped Gauss-Newton direction on every direction and
shortens it by a line search. On a 256-storey frame with 513 parameters, J^T J had
eigenvalues from 1e-17 to 1 of its largest; IPOPT backtracked 9-10 times per iteration to
steps of 0.002 (complex prefit: f 0.82 after 24 iterations of 7 s, the noise floor 0.44),
and on a 64-storey frame it reached the log-magnitude minimum and then kept stepping
along the top storeys' near-null direction (eigenvalue 2e-16 of the largest) for 500
iterations. Measured, docs/method/updating.md.
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from nlp.solve.identify import tangent_basis
from nlp.solve.stopping import free_variables

__all__ = ["LM_STATIONARY", "PREFIT_HANDOVER", "LM_FROM", "LMResult", "determined_directions",
           "levenberg_marquardt", "lm_chosen"]

# Stop when the Gauss-Newton step on the determined directions would lower 2 f by less
# than this many residual variances s^2: the step is below 0.1 standard error
LM_STATIONARY = 1e-2
# A prefit hands over to the case's residual when its step would lower 2 f by less than
# this many s^2 (a step below 10 standard errors: near the minimum, in its basin)
PREFIT_HANDOVER = 100.0
# Free variables above which the numeric backends' solves are LM by default (IPOPT below):
# between the largest tall frame IPOPT finished (129 parameters: 4 starts in 25 s) and the
# smallest it did not (257: still running after 4 minutes; 513: line search stalled at
# twice the noise floor), docs/method/updating.md
LM_FROM = 200
# Initial damping relative to diag(J^T J). From the nominal model of a 64-storey frame
# (129 parameters, complex prefit) 1e-3 took a near Gauss-Newton first step into another
# minimum (top storeys 11-24 % off, f 2 % above the truth's); 0.1, 1 and 10 all reached the
# minimum below the truth's f, 0.1 in the fewest steps (11 + 7)
_MU0 = 0.1
_MU_MAX = 1e16       # damping at which the step is lost in round-off: stalled


@dataclass(frozen=True)
class LMResult:
    """z, f, status, accepted steps, evaluations (values and normal equations), and the
    number of determined directions at the last point."""

    z: np.ndarray
    f: float
    success: bool
    status: str
    iterations: int
    evaluations: int
    determined: int = 0


def lm_chosen(setting, n_z):
    """Solve by LM? setting: True, False, or None (the default: above LM_FROM free
    variables). Below it IPOPT is faster: on tall frames of 32-64 storeys LM prefits from
    far search starts handed over at local minima of the complex residual, where IPOPT then
    crept on ln|H| for 500 iterations (whole run 284 s against 25 s at 64 storeys); above
    it IPOPT's undamped steps along the nearly null directions of J^T J stall."""
    return n_z > LM_FROM if setting is None else bool(setting)


def free_eigen(z, g, A, lo, hi, G):
    """(W (n_z, k), lambda (k,)): the eigenvectors and eigenvalues of A = J^T J on the
    free variables (:func:`nlp.solve.stopping.free_variables`, held ones excluded) along
    G s = 0, ascending."""
    free = free_variables(z, g, lo, hi) & (lo < hi)
    N = tangent_basis(None if G is None else G[:, free], int(free.sum()))
    lam, V = np.linalg.eigh(N.T @ A[np.ix_(free, free)] @ N)
    W = np.zeros((z.size, lam.size))
    W[free] = N @ V
    return W, lam


def determined_directions(z, g, A, lo, hi, G, s2):
    """(B (n_z, k), lambda (k,)): the free directions (:func:`free_eigen`) whose eigenvalue
    of J^T J exceeds the residual variance s2."""
    W, lam = free_eigen(z, g, A, lo, hi, G)
    keep = lam > max(s2, 1e-14 * max(float(lam[-1]) if lam.size else 0.0, 1e-300))
    return W[:, keep], lam[keep]


def _split(W, lam, g, s2, undetermined=True):
    """The directions of the next steps, their eigenvalues, and the stopping measures:
    the decrement of 2 f on the determined directions, and 2 |g| along the undetermined
    ones (the chi-square a whole unit step there would gain, to first order). While that
    gain exceeds s^2 the steps use every direction (damped), else the determined ones."""
    keep = lam > max(s2, 1e-14 * max(float(lam[-1]) if lam.size else 0.0, 1e-300))
    gW = W.T @ g
    dec = float(np.sum(gW[keep] ** 2 / lam[keep]))
    gain = 2 * float(np.linalg.norm(gW[~keep]))
    if gain > s2 and undetermined:
        return W, np.maximum(lam, 0.0), dec, gain
    return W[:, keep], lam[keep], dec, gain


def levenberg_marquardt(normal, value, z0, lo, hi, dof, max_iter=50, G=None, h=None,
                        tol=LM_STATIONARY, undetermined=True, monitor=None):
    """Minimise 1/2 ||r(z)||^2 in [lo, hi] (and G z = h) from z0.

    Parameters
    ----------
    normal : callable z -> (f, g, A): f = 1/2 r^T r, g = J^T r, A = J^T J.
    value : callable z -> f (a trial point: no Jacobian needed).
    dof : residuals minus variables (s^2 = 2 f / dof).
    max_iter : accepted steps at most (status ``Maximum_Iterations_Exceeded`` there).
    G, h : optional linear equality constraints G z = h; z0 is first moved onto them.
    undetermined : also require that a unit step along the undetermined directions would
        gain less than s^2 to first order (False: a prefit, handed over near its minimum).
    monitor : optional callable(iteration, f, mu, decrement / s^2, directions stepped on).

    Returns an :class:`LMResult`; ``success`` when the Gauss-Newton decrement of 2 f on
    the determined directions is below ``tol`` s^2 (or 0) at a feasible point.
    """
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    z = np.clip(np.asarray(z0, float), lo, hi)
    if G is not None and G.shape[0]:  # onto G z = h (the nearest point), then into the box
        z = np.clip(z + G.T @ np.linalg.solve(G @ G.T, h - G @ z), lo, hi)
    f, g, A = normal(z)
    evals, it, mu, nu, moved = 1, 0, _MU0, 2.0, True
    while True:
        if moved:  # a new point: its determined directions and the stopping test
            if not (np.isfinite(f) and np.all(np.isfinite(g))):
                return LMResult(z, f, False, "Invalid_Number_Detected", it, evals, 0)
            s2 = 2 * f / max(dof, 1)
            B, lam, dec, gain = _split(*free_eigen(z, g, A, lo, hi, G), g, s2, undetermined)
            gB = B.T @ g
            if monitor is not None:
                monitor(it, f, mu, dec / s2 if s2 > 0 else 0.0, lam.size)
            if (dec <= tol * s2 and (gain <= s2 or not undetermined)) or dec + gain <= 1e-300:
                ok = G is None or not G.shape[0] or np.allclose(G @ z, h, rtol=1e-9, atol=1e-12)
                text = (f"Stationary (Levenberg-Marquardt: Gauss-Newton decrement {dec / s2:.1e} "
                        f"s^2 on the determined directions)" if s2 > 0 else
                        "Stationary (Levenberg-Marquardt: zero residual)") if ok else \
                    "Infeasible (the total-mass anchor is not met inside the bounds)"
                return LMResult(z, f, ok, text, it, evals, lam.size)
            if it >= max_iter:
                return LMResult(z, f, False, "Maximum_Iterations_Exceeded", it, evals, lam.size)
            ABB = np.diag(lam)  # B^T A B: B holds eigenvectors
            DBB = B.T @ (np.maximum(np.diag(A), 1e-300)[:, None] * B)
            moved = False
        if mu > _MU_MAX:
            return LMResult(z, f, False, "Stalled (Levenberg-Marquardt damping at its limit)", it,
                            evals, lam.size)
        try:
            s = B @ sla.cho_solve(sla.cho_factor(ABB + mu * DBB), -gB)
        except (np.linalg.LinAlgError, ValueError):
            mu, nu = mu * nu, 2 * nu
            continue
        s = np.clip(z + s, lo, hi) - z
        pred = -(g @ s + 0.5 * s @ A @ s)
        f_new = value(z + s) if pred > 0 else np.inf
        evals += 1
        rho = (f - f_new) / pred if pred > 0 and np.isfinite(f_new) else -1.0
        if rho > 1e-4:
            z = z + s
            f, g, A = normal(z)
            evals, it, moved = evals + 1, it + 1, True
            mu *= max(1 / 3, 1 - (2 * rho - 1) ** 3)
            nu = 2.0
        else:
            mu, nu = mu * nu, 2 * nu
