"""When a local solve of the updating NLP stops: tolerances and the stationarity test.

IPOPT's absolute tolerance on the gradient cannot be met where the misfit is large, so a
solve also stops where a Gauss-Newton step would lower the chi-square 2 f by less than
:data:`STATIONARY` (:func:`gauss_newton_decrement`), checked by an IPOPT iteration
callback (:class:`StopWhenStationary`).
"""

import casadi as ca
import numpy as np

from nlp.solve.identify import tangent_basis

__all__ = ["SCREEN_TOL", "STATIONARY", "STATIONARY_EVERY", "STATIONARY_FROM", "POLISH_AT", "LIMIT_STATUSES",
           "gauss_newton_decrement", "free_variables", "decrement_normal", "StopWhenStationary"]

SCREEN_TOL = 1e-5  # IPOPT tol of screening solves (the default tol is 1e-8)
# A point is stationary when a Gauss-Newton step would lower the chi-square 2 f by less than
# this: every parameter step below ~1e-3 of its standard error. IPOPT's absolute tolerance on
# the gradient cannot be met where the misfit is large (a model missing physics: f ~ 4e4 left
# |grad f| at 5e-4 after 3,000 iterations with f settled to 12 digits), so such solves crawl
# to max_iter; they stop here instead, and count as converged.
STATIONARY = 1e-6
STATIONARY_EVERY = 10   # IPOPT iterations between two stationarity checks ...
STATIONARY_FROM = 50    # ... from this iteration on (a solve that converges sooner pays nothing)
# A Gauss-Newton solve of a well-posed fit converges in tens of iterations (20 on the
# four-storey case); one still going here is creeping along a direction that J^T J misses
# (large residuals). It is stopped once to try Newton steps on the full Hessian from a
# convex point (nlp.solve.polish), and resumed when they do not reach a minimum.
POLISH_AT = 100
#: solver statuses of a solve stopped by its iteration or time limit
LIMIT_STATUSES = ("Maximum_Iterations_Exceeded", "Maximum_CpuTime_Exceeded",
                  "Maximum_WallTime_Exceeded", "Max_Iter_Exceeded")


def free_variables(z, g, lo, hi):
    """The variables a descent step may move: not on a bound the gradient g presses them on."""
    near = 1e-7 * np.maximum(1.0, np.abs(z))
    return ~(((z <= lo + near) & (g > 0)) | ((z >= hi - near) & (g < 0)))


def gauss_newton_decrement(z, r, J, lo, hi, G):
    """g^T (J^T J)^+ g on the steps that keep the bounds active where the gradient
    g = J^T r presses on them and the linear equality constraints G dz = 0 satisfied.

    z, lo, hi : (n_z,); r : (n_r,) residuals and J : (n_r, n_z) their Jacobian at z;
    G : (n_g, n_z). The chi-square decrease a Gauss-Newton step from z would give.
    """
    g = J.T @ r
    if not np.all(np.isfinite(g)):
        return np.inf
    free = free_variables(z, g, lo, hi)
    N = tangent_basis(G[:, free], int(free.sum()))
    JN, gN = J[:, free] @ N, N.T @ g[free]
    return float(gN @ np.linalg.pinv(JN.T @ JN) @ gN)


def decrement_normal(z, g, A, lo, hi, G=None):
    """:func:`gauss_newton_decrement` from the normal equations, g = J^T r and A = J^T J
    (no J: n_z^2 memory, and no n_r n_z^2 product with the tangent basis)."""
    if not np.all(np.isfinite(g)):
        return np.inf
    free = free_variables(z, g, lo, hi)
    N = tangent_basis(None if G is None else G[:, free], int(free.sum()))
    gN = N.T @ g[free]
    return float(gN @ np.linalg.pinv(N.T @ A[np.ix_(free, free)] @ N) @ gN)


class StopWhenStationary(ca.Callback):
    """IPOPT iteration callback: asks the solver to stop at a stationary point
    (``decrement(x)`` below :data:`STATIONARY`), and once at iteration ``polish_at`` when
    that is set (``early`` then says it stopped there)."""

    def __init__(self, decrement, nx, ng, np_):
        ca.Callback.__init__(self)
        self._decrement, self._n = decrement, {"x": nx, "lam_x": nx, "g": ng, "lam_g": ng,
                                               "f": 1, "lam_p": np_}
        self.calls = 0   # reset by UpdatingProblem.solve, with polish_at and early
        self.polish_at, self.early = None, False
        self.construct("stop_when_stationary", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "stop"

    def get_sparsity_in(self, i):
        n = self._n.get(ca.nlpsol_out(i), 0)
        return ca.Sparsity.dense(n, 1) if n else ca.Sparsity(0, 0)

    def eval(self, args):
        self.calls += 1
        if self.polish_at is not None and (self.calls - 1) * STATIONARY_EVERY >= self.polish_at:
            self.polish_at, self.early = None, True
            return [1]
        if self.calls * STATIONARY_EVERY < STATIONARY_FROM:
            return [0]
        x = np.asarray(args[0], float).ravel()
        try:
            return [1 if self._decrement(x) < STATIONARY else 0]
        except Exception:  # an iterate where r cannot be evaluated: let IPOPT go on
            return [0]
