"""Refuse impossible cases before solving.

Each check raises one :class:`nlp.errors.InputError` naming the file and the
key (or column) at fault, so that no solve starts on a case that can only give
a wrong answer: matrices that are not symmetric, a scale anchor that cannot be
met, fewer residuals than free parameters, a dead channel or input, residuals
that are not finite at the start point.
"""

import numpy as np

from nlp.errors import InputError
from nlp.frf.freqsel import band_mask

__all__ = ["check_model_matrices", "check_free_parameters", "check_total_mass",
           "check_data_points", "check_points_inside", "check_frf_alive", "check_record_alive",
           "check_coherence", "check_start_residuals", "SYM_RTOL", "MIN_COHERENCE"]

SYM_RTOL = 1e-8        # |A - A^T| allowed, relative to max |A| (round-off of exported models)
MIN_COHERENCE = 0.5    # a channel whose H1 coherence never reaches this is not driven by the input


def _asymmetry(A):
    scale = max(float(np.max(np.abs(A))), 1e-300)
    return float(np.max(np.abs(A - A.T))) / scale


def check_model_matrices(file, M0, K0, M_infl, K_infl):
    """M0 symmetric positive definite, K0 symmetric positive semi-definite,
    every influence matrix symmetric (Eqns 23-24 keep M and K symmetric only then)."""
    for key, A in [("M0", M0), ("K0", K0)] + [(f"M_infl[{i}]", A) for i, A in enumerate(M_infl)] \
            + [(f"K_infl[{i}]", A) for i, A in enumerate(K_infl)]:
        a = _asymmetry(np.asarray(A, float))
        if a > SYM_RTOL:
            raise InputError(file, key, "a symmetric matrix",
                             f"max |A - A^T| / max |A| = {a:.3g}")
    lam_m = np.linalg.eigvalsh(M0)
    if lam_m.min() <= 0:
        raise InputError(file, "M0", "a positive definite mass matrix",
                         f"smallest eigenvalue {float(lam_m.min()):.6g}")
    lam_k = np.linalg.eigvalsh(K0)
    if lam_k.min() < -1e-9 * max(abs(float(lam_k.max())), 1e-300):
        raise InputError(file, "K0", "a positive semi-definite stiffness matrix",
                         f"smallest eigenvalue {float(lam_k.min()):.6g}")


def check_free_parameters(case_file, params):
    """At least one decision variable: a case with every parameter fixed has nothing to update."""
    if params.n_z == 0:
        raise InputError(case_file, "parameters.fixed", "at least one free parameter to update",
                         "every parameter fixed")


def total_mass_range(model, params):
    """Smallest and largest total mass 1^T M 1 [kg] reachable within the bounds."""
    sb = params.slices()[1]
    s = np.array([float(np.sum(Mr)) for Mr in model.M_infl])
    T, c = params.T[sb], params.c[sb]
    a = float(np.sum(model.M0)) + float(s @ c)
    g = s @ T
    lo, hi = params.z_bounds
    return a + float(np.sum(np.minimum(g * lo, g * hi))), a + float(np.sum(np.maximum(g * lo, g * hi)))


def check_total_mass(case_file, model, params, total_mass):
    """The total-mass anchor must be reachable with the fixed masses and the mass bounds."""
    if total_mass is None:
        return
    lo, hi = total_mass_range(model, params)
    tol = 1e-9 * max(abs(total_mass), 1.0)
    if not lo - tol <= total_mass <= hi + tol:
        fixed = [p for p in params.params if p.group == "mass" and p.fixed]
        what = (f"a total mass between {lo:.6g} and {hi:.6g} kg (what the fixed masses "
                f"{', '.join(p.name for p in fixed) or '(none)'} and the mass bounds allow)")
        if abs(hi - lo) <= tol:
            what = f"{lo:.6g} kg, the sum of the fixed masses (every mass is fixed)"
        raise InputError(case_file, "parameters.total_mass", what, float(total_mass))


def _frequency_key(cfg):
    fc = cfg.frequencies
    return {"points": "frequencies.points", "bands": "frequencies.bands"}.get(
        fc.method, "frequencies.fmin" if fc.fmin is not None or fc.fmax is not None
        else "frequencies.method")


def check_points_inside(cfg, f):
    """Listed frequency points and bands must lie inside the data's range."""
    fc = cfg.frequencies
    step = float(np.median(np.diff(f))) if f.size > 1 else 0.0
    lo, hi = float(f[0]) - step, float(f[-1]) + step
    if fc.method == "points":
        for i, p in enumerate(fc.points):
            if not lo <= p <= hi:
                raise InputError(cfg.path, f"frequencies.points[{i}]",
                                 f"a frequency inside the data's range {f[0]:g}-{f[-1]:g} Hz",
                                 float(p))
    if fc.method == "bands":
        for i, (a, b) in enumerate(fc.bands):
            if b < f[0] or a > f[-1]:
                raise InputError(cfg.path, f"frequencies.bands[{i}]",
                                 f"a band that overlaps the data's range {f[0]:g}-{f[-1]:g} Hz",
                                 [float(a), float(b)])


def check_data_points(cfg, params, n_channels, n_freq, f):
    """More residuals than free parameters (at least one degree of freedom for the noise)."""
    per = 2 if cfg.objective.residual == "complex" else 1
    n_res = per * n_channels * n_freq
    n_z = params.n_z
    if n_res <= n_z:
        raise InputError(cfg.path, _frequency_key(cfg),
                         f"settings that keep more residuals than the {n_z} free parameters "
                         f"inside the data's range {f[0]:g}-{f[-1]:g} Hz",
                         f"{n_freq} frequency points x {n_channels} channels = {n_res} residuals")


def check_frf_alive(cfg, H, rows):
    """Every used FRF column has a non-zero value somewhere."""
    for i, c in enumerate(cfg.data.channels):
        if c.column in rows and not np.any(np.abs(H[c.column]) > 0):
            raise InputError(cfg.data.file, f"column {c.column}",
                             f"a non-zero FRF for channel '{c.name}' (data.channels[{i}] of "
                             f"{cfg.path})", "all zeros")


def check_record_alive(records_file, column, x, case_key):
    """A record that varies: an all-zero or constant record carries no FRF."""
    x = np.asarray(x, float)
    if x.size == 0 or not np.any(np.abs(x - x.mean()) > 1e-12 * max(np.max(np.abs(x)), 1e-300)):
        raise InputError(records_file, column, f"a varying record ({case_key})",
                         f"constant {float(x[0]) if x.size else 'empty'}")


def check_coherence(cfg, f, coherence, names, keys, n_averages, source=None):
    """Each output must be coherent with the input somewhere in the band (H1 estimates
    from several averages only: with one average the coherence is 1 by construction);
    source: the records file named in the error (default: the case's data.file)."""
    if coherence is None or n_averages < 16:
        return
    # the loader validated fmin < fmax already: band_mask cannot refuse them here
    band = (f > 0) & band_mask(f, cfg.frequencies.fmin, cfg.frequencies.fmax)
    for c, (name, key) in enumerate(zip(names, keys)):
        top = float(np.max(coherence[c, band])) if band.any() else 0.0
        if top < MIN_COHERENCE:
            raise InputError(source or cfg.data.file, name, f"a response coherent with the input somewhere "
                             f"(coherence >= {MIN_COHERENCE} at some frequency; {key} in "
                             f"{cfg.path})", f"largest coherence {top:.3f}")


def check_start_residuals(case, problem):
    """Residuals at the start point are finite; else name the channel and frequency."""
    z0 = np.clip(problem.z0, *problem.bounds)
    with np.errstate(all="ignore"):
        r, J = problem.residuals(z0)
    tg = problem.target
    N = tg.omega.size
    R = r.reshape(N, -1)
    bad = ~np.isfinite(R) | ~np.isfinite(J).all(axis=1).reshape(N, -1)
    if not bad.any():
        return
    k, e = np.argwhere(bad)[0]
    per = R.shape[1] // len(tg.channels)
    name = tg.channels[e // per].name
    idx = next((i for i, c in enumerate(case.config.data.channels) if c.name == name), None)
    H = tg.H[e // per, k]
    why = "the measured FRF is zero there" if H == 0 else "the model FRF is not finite there"
    raise InputError(case.config.path, "data.channels" + ("" if idx is None else f"[{idx}]"),
                     f"data that give finite residuals at the start point (channel '{name}')",
                     f"non-finite residual at {tg.omega[k] / (2 * np.pi):.6g} Hz; {why}")
