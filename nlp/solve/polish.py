"""Newton polish of a least-squares optimum where the Gauss-Newton solver stops short.

IPOPT is given the Gauss-Newton Hessian J^T J (cheap, positive semi-definite). Where
the residuals are large (physics the model lacks) and the problem is curved, J^T J
misses the second-order term sum r_i grad^2 r_i, and along a weakly determined
direction (entries of a general C) the solver creeps to its iteration limit. Measured
on a blind 5-storey frame with 25 parameters (docs/benchmarks/history.md): 3000
iterations, a Gauss-Newton decrement of 325 at the end, and a Hessian with
eigenvalues from 0.02 to 7e8. Newton steps on the
full Hessian reach a stationary point from there in a few steps.

The Hessian is the central finite difference of the exact gradient J^T r (2 n_z
gradient evaluations per step), which is affordable for the tens of parameters of a
shear frame; bounds hold a variable where the gradient or the Newton step presses it
against one, and equality constraints that are linear (the total-mass anchor, Eqn 24)
are kept by stepping in their null space.
"""

import numpy as np

from nlp.solve.identify import tangent_basis

__all__ = ["newton_polish", "NEWTON_STATIONARY", "MAX_PARAMETERS"]

# A point is a minimum when the Newton step would lower the chi-square 2 f by less than
# this (its length is then ~0.01 standard errors in the metric of the Hessian)
NEWTON_STATIONARY = 1e-4
MAX_PARAMETERS = 60      # beyond this the finite-difference Hessian costs more than it saves


def _hessian(grad, z, free, lo, hi):
    """Central finite-difference Hessian of f on the free variables (steps kept in bounds)."""
    idx = np.where(free)[0]
    H = np.empty((idx.size, idx.size))
    for j, i in enumerate(idx):
        h = 1e-5 * max(1.0, abs(z[i]))
        up, dn = min(z[i] + h, hi[i]), max(z[i] - h, lo[i])
        zu, zd = z.copy(), z.copy()
        zu[i], zd[i] = up, dn
        H[:, j] = (grad(zu)[idx] - grad(zd)[idx]) / (up - dn)
    return 0.5 * (H + H.T)


def newton_polish(fg, z, lo, hi, G=None, max_steps=30, tol=NEWTON_STATIONARY, convex_start=False):
    """Newton steps on f from z inside [lo, hi] and on G dz = 0; with convex_start, none
    unless the Hessian at z is positive definite (z lies in the bowl of one minimum).

    Parameters
    ----------
    fg : callable
        z -> (f, gradient), f = 0.5 chi-square.
    z : (n_z,) ndarray
        Feasible start.
    lo, hi : (n_z,) ndarray
        Bounds; lo == hi holds a variable.
    G : (n_g, n_z) ndarray, optional
        Jacobian of linear equality constraints (already satisfied at z).

    Returns
    -------
    z : ndarray
        Last point (never worse than the start).
    f : float
    decrement : float
        g^T H^-1 g on the free subspace at z: the decrease of the chi-square 2 f a
        Newton step would give; inf where H is not positive definite (not a minimum).
    stationary : bool
        decrement < tol.
    steps : int
    """
    z = np.clip(np.asarray(z, float), lo, hi)
    f, g = fg(z)
    dec = np.inf
    if not (np.isfinite(f) and np.all(np.isfinite(g))):
        return z, f, dec, False, 0
    for step in range(max_steps + 1):
        near = 1e-9 * np.maximum(1.0, np.abs(z))
        at_lo, at_hi = z <= lo + near, z >= hi - near
        free = (hi - lo > 0) & ~((at_lo & (g > 0)) | (at_hi & (g < 0)))
        idx0 = np.flatnonzero(free)
        if idx0.size == 0:
            return z, f, 0.0, True, step
        H0 = _hessian(lambda x: fg(x)[1], z, free, lo, hi)
        if not (np.all(np.isfinite(H0)) and np.all(np.isfinite(g[free]))):
            return z, f, np.inf, False, step   # a neighbour where the model cannot be evaluated
        newton = _active_set_step(H0, g, z, free, idx0, at_lo, at_hi, G)
        if newton is None:
            return z, f, 0.0, True, step
        dz, free, pd, dec = newton
        if convex_start and step == 0 and not pd:
            return z, f, np.inf, False, 0
        dec += _held_decrement(H0, g, idx0, free, at_lo, at_hi)
        if pd and dec < tol:
            return z, f, dec, True, step
        if step == max_steps:
            break
        found = _line_search(fg, z, f, g, dz, free, lo, hi)
        if found is None:
            return z, f, dec, False, step
        z, f, g = found
    return z, f, dec, bool(dec < tol), max_steps


def _active_set_step(H0, g, z, free, idx0, at_lo, at_hi, G):
    """(dz, free, positive definite, decrement) of the modified Newton step on the free
    variables ``free`` (indices idx0 into H0) and on G dz = 0; None when every variable
    ends held on a bound."""
    # active set: a variable on a bound that the Newton step would push out is held
    # as well (the Hessian couples it to the others) and the step is taken again
    for _ in range(idx0.size):
        keep = np.isin(idx0, np.flatnonzero(free))
        Gf = None if G is None else np.asarray(G, float)[:, free]
        N = tangent_basis(Gf, int(free.sum()))
        H = N.T @ H0[np.ix_(keep, keep)] @ N
        gN = N.T @ g[free]
        ev, V = np.linalg.eigh(H) if H.size else (np.ones(0), np.zeros((0, 0)))
        # modified Newton: a non-convex point takes the step of |H| (a descent direction)
        scale = max(float(np.abs(ev).max()), 1e-300) if ev.size else 1.0
        evm = np.maximum(np.abs(ev), 1e-12 * scale)
        dy = -V @ ((V.T @ gN) / evm)
        dz = np.zeros_like(z)
        dz[free] = N @ dy
        out = free & ((at_lo & (dz < -1e-15)) | (at_hi & (dz > 1e-15)))
        if not out.any():
            break
        free = free & ~out
        if not free.any():
            return None
    pd = bool(ev.size == 0 or ev.min() > 1e-12 * scale)
    dec = float(gN @ V @ ((V.T @ gN) / evm)) if pd and ev.size else (0.0 if pd else np.inf)
    return dz, free, pd, dec


def _held_decrement(H0, g, idx0, free, at_lo, at_hi):
    """What moving alone each variable held on its bound with its gradient pointing inside
    would gain, g_i^2 / H_ii: such a point is not at a minimum."""
    held = np.isin(idx0, np.flatnonzero(free), invert=True)
    if not held.any():
        return 0.0
    gi, hii = g[idx0[held]], np.diag(H0)[held]
    wrong = (at_lo[idx0[held]] & (gi < 0)) | (at_hi[idx0[held]] & (gi > 0))
    with np.errstate(over="ignore"):   # a flat direction: inf, not a minimum
        return float(np.sum(gi[wrong] ** 2 / np.maximum(hii[wrong], 1e-300)))


def _line_search(fg, z, f, g, dz, free, lo, hi):
    """(z, f, gradient) after a backtracking (Armijo) step along dz, or None."""
    # the longest step inside the bounds, so the equality stays satisfied
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(dz > 0, (hi - z) / dz, np.where(dz < 0, (lo - z) / dz, np.inf))
    s = min(1.0, float(np.min(room)))
    while s > 1e-6:
        z_new = np.clip(z + s * dz, lo, hi)
        f_new, g_new = fg(z_new)
        if np.isfinite(f_new) and f_new <= f + 1e-4 * s * float(g[free] @ dz[free]):
            return z_new, f_new, g_new
        s *= 0.5
    return None
