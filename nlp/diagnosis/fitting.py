"""The updating problem of a diagnosis: built on the fitted points, solved, its residuals.

The baseline and every candidate refit share these pieces: a target whose residuals are
divided by the route's noise level (so the objective is half a chi-square), the NLP of
:mod:`nlp.solve.problem` with the candidate's physics added, a scatter search over it, and the
fitted half-power windows (the held-out shoulders are the same windows widened).
"""

from dataclasses import replace

import numpy as np

from nlp.case.selection import half_power_points
from nlp.frf.noise import sigma_ln
from nlp.diagnosis.calibration import calibration_of
from nlp.diagnosis.families import extend_parameters, references
from nlp.diagnosis.locations import fe_references, is_fe
from nlp.diagnosis.reduction import basis_of, uses_reduced
from nlp.errors import SearchFailed
from nlp.frf.backends.terms import proportional
from nlp.solve.problem import SolverConfig, Target, UpdatingProblem
from nlp.solve.search import scatter_search
from nlp.diagnosis.evidence import quasi_covariance
from nlp.solve.identify import tangent_basis


# ---------------------------------------------------------------------- noise
def noise_sigma(case, idx):
    """Standard deviation of ln|H| at points idx of every channel: (n_ch, len(idx)),
    per frequency, from the noise model of the case's FRF route (nlp/noise.py)."""
    return sigma_ln(case, idx)


# ------------------------------------------------------------------ problems
def fit_target(case, idx, sigma):
    """The case's target at points idx, each residual divided by its noise level sigma."""
    tg = case.target
    return Target(omega=2 * np.pi * case.f[idx], H=case.H[:, idx], weight=1.0 / sigma,
                  channels=tg.channels, excitation=tg.excitation, force_dof=tg.force_dof,
                  ground_r=tg.ground_r, kernel=tg.kernel)


def diagnosis_problem(case, target, enrichments=(), values=None, compile=True, optimize=True,
             damping=None, max_iter=None, residual=None):
    """The updating NLP; optimize=False compiles quicker, slower-running C (a refit).

    damping : optional (damping model, its ParameterSet) in place of the case's (the
    structured damping refit); the added physics keeps the case's reference values.
    max_iter : optional cap on the solver's iterations (below the case's own); a capped
        problem is not finished by Newton steps where it stops (nlp/polish.py).
    residual : optional residual form in place of the case's (the loss check's complex refit).
    """
    cfg = case.config
    refs = case_references(case)
    # the calibration within its tolerance and the model error stay in every fit, so
    # candidates are judged with them present (nlp.diagnosis.calibration, .discrepancy);
    # their parameters come first among the added ones, the calibration's before
    cal = calibration_of(case)
    kept = ((cal,) if cal is not None else ()) + tuple(case.discrepancy)
    if kept:
        if values is not None:
            values = [e.spec(refs)["initial"] for e in kept] + list(values)
        enrichments = kept + tuple(enrichments)
    damping, base_params = damping if damping is not None else (case.damping, case.params)
    params = extend_parameters(base_params, enrichments, refs, values)
    options = dict(cfg.solver.options)
    if max_iter is not None:
        key = "ipopt.max_iter" if "ipopt.max_iter" in options else "max_iter"
        options[key] = min(int(options.get(key, max_iter)), max_iter)
    solver = SolverConfig(cfg.solver.name, options, compile, optimize)
    if residual is None:
        residual = "complex" if cfg.objective.residual == "complex" else "log_magnitude"
    reduced = uses_reduced(case)  # a large FE model: every fit on one re-centred basis
    pr = UpdatingProblem(case.model, damping, params, target, residual=residual,
                         solver=solver, total_mass=cfg.parameters.total_mass,
                         enrichments=enrichments, refs=refs,
                         frf_backend="reduced" if reduced else "auto",
                         basis=basis_of(case) if reduced else None)
    # on the numeric backends (FE models) Levenberg-Marquardt prefits and solves: IPOPT spent
    # 92 % of a planted-support baseline backtracking its line search on full FRF evaluations
    # (56 min unfinished); from the same far starts LM took 4-5 s a start against 18-40 s and
    # reached a lower minimum (docs/method/diagnosis.md, "Families on FE models")
    pr.lm_prefit = pr.lm_local = pr.backend != "dense"
    # a capped refit bounds its optimum and is continued when adopted (refit.continue_refit);
    # Newton steps from wherever each of its starts stopped cost more than the cap saves
    # (minutes per round on a refit of a few thousand residuals and some 30 parameters;
    # see docs/method/diagnosis.md)
    pr.polish_unconverged = max_iter is None
    # its objective is half a chi-square, the unit of the polish's stationarity test
    pr.early_polish = True
    return pr


def normalised(problem, z, case, idx, sigma):
    """Residuals over noise: ln|Ha/Hx|, or |ln(Ha/Hx)| / sqrt(2) when phase is fitted."""
    if len(idx) == 0:   # windows widened over the whole band leave no held-out shoulder
        return np.zeros((len(case.channels), 0))
    Ha = problem.channel_frfs(z, 2 * np.pi * case.f[idx])
    d = np.log(Ha / case.H[:, idx])
    if case.config.objective.residual == "complex":
        return np.abs(d) / np.sqrt(2) / sigma
    return d.real / sigma


class _Kept:
    """Collects every finished start of a scatter search (the checkpoint interface)."""

    def __init__(self):
        self.results = {}

    def open(self, problem, config, starts):
        return {}

    def append(self, i, res):
        self.results[i] = res

    def close(self):
        pass


def scatter_best(problem, config, setup=None):
    """Scatter search; (best result, converged). When no start converged (a solver that
    crawls along a weakly determined direction until its iteration limit), the lowest
    objective reached is used, as every f is a true evaluation at a feasible point, and
    converged is False (diagnosis.json says so)."""
    kept = _Kept()
    try:
        search = scatter_search(problem, config, progress=None, checkpoint=kept, setup=setup)
    except SearchFailed:
        finite = [r for r in kept.results.values() if np.isfinite(r.f)]
        if not finite:
            raise
        return min(finite, key=lambda r: r.f), False
    if search.interrupted:
        # a diagnosis goes on from this optimum: a search cut short by Ctrl-C would change
        # what follows, so the interruption stops the diagnosis (diagnose --resume)
        raise KeyboardInterrupt("interrupted during a scatter search")
    return search.best, True


def best_fit(problem, z0_list):
    """The lowest-objective local solve of problem from the starts z0_list."""
    best = None
    for z0 in z0_list:
        r = problem.solve(z0)
        if best is None or r.f < best.f:
            best = r
    return best


def continued(pr, res, times=3):
    """res re-solved from where it stopped, up to ``times`` more, until it converges."""
    for _ in range(times):
        if res.success:
            break
        again = pr.solve(res.z)
        if again.success or again.f < res.f:
            res = again
    return res


def case_references(case):
    """Reference values of the added physics (nlp.diagnosis.families.references) for case;
    an FE model's come from its floors (nlp.diagnosis.locations.fe_references)."""
    if is_fe(case.model):
        tg = case.target
        refs = fe_references(case.model, case.damping, tg.ground_r,
                             tuple(ch.dof for ch in tg.channels))
    else:
        refs = references(case.model, getattr(case.damping, "C0", np.eye(case.model.n)))
    # a flexible base extends a Rayleigh law over its DOF (families.BaseFlexibility)
    return {**refs, "rayleigh": proportional(case.damping)}


def signed(problem, z, case, idx, sigma):
    """Signed residuals over noise, the objective's own (nlp/problem.py): (n_ch, n) of
    ln|Ha/Hx| / sigma, or with the phase (2 n_ch, n) of the real and imaginary parts of
    (Ha - Hx) / |Hx| / sigma. Their sum of squares is the chi-square (2 x objective)."""
    Ha = problem.channel_frfs(z, 2 * np.pi * case.f[idx])
    Hx = case.H[:, idx]
    if case.config.objective.residual == "complex":
        d = (Ha - Hx) / np.abs(Hx) / sigma
        return np.vstack([d.real, d.imag])
    return np.log(np.abs(Ha / Hx)) / sigma


def quasi_se(pr, z, free=None, rj=None):
    """Standard errors of theta at z, inflated by the remaining misfit (quasi-likelihood).

    free : optional boolean mask of the decision variables the solve left free (the
    others held by its bounds carry no error).
    rj : (r, J) at z when the caller has them already (pr.residuals(z)).
    """
    free = np.ones(pr.params.n_z, bool) if free is None else np.asarray(free, bool)
    r, J = pr.residuals(z) if rj is None else rj
    G = pr.constraint_jacobian()
    G = G[:, free] if G.size else G
    cov, _ = quasi_covariance(J[:, free], r, max(pr.n_used - int(free.sum()) + G.shape[0], 1), G)
    T = pr.params.T[:, free]
    return np.sqrt(np.clip(np.diag(T @ cov @ T.T), 0, None)), cov


def projected_columns(pr, J, k):
    """(Q, Je, Jp): an orthonormal basis Q of the current model's columns of the Jacobian J
    (on the total-mass constraint's tangent space when the case anchors its mass), the last
    k variables' columns Je, and Je projected off Q: what a candidate can change that the
    model cannot."""
    Jb, Je = J[:, :-k], J[:, -k:]
    G = pr.constraint_jacobian()
    if G.size:
        # only steps that keep the total-mass anchor: the baseline moves on its constraint
        # surface, and a candidate that adds mass is paired with the least compensating step
        Jb = Jb @ tangent_basis(G[:, :-k], Jb.shape[1])
        E = np.zeros((J.shape[1], k))
        E[-k:] = np.eye(k)
        Je = J @ (E - np.linalg.pinv(G) @ (G @ E))
    Q, _ = np.linalg.qr(Jb)
    return Q, Je, Je - Q @ (Q.T @ Je)


def fit_windows(cfg, case, mult, windows=False):
    """Points within mult x k half-power bandwidths of the peaks (mult 1: the case's own
    selection, unless ``windows``)."""
    if mult == 1 and not windows:
        return case.selected
    c = replace(cfg, frequencies=replace(cfg.frequencies, k=mult * cfg.frequencies.k))
    idx = np.asarray(half_power_points(c, case.f, case.H, case.channels, case.target.excitation,
                                 case.coherence, case.noise.detect), int)
    return idx[case.f[idx] > 0]


def with_values(pr, z_cur, values):
    """Decision vector: the current model's, then the new enrichment's parameters."""
    k = len(values)
    theta = pr.theta(np.concatenate([z_cur, np.zeros(pr.params.n_z - z_cur.size)]))
    theta[-k:] = values
    return np.concatenate([z_cur, pr.params.z_from_theta(theta)[z_cur.size:]])


def window_bands(f_idx):
    """Contiguous groups of fitted points: one band per half-power window."""
    groups, start = [], 0
    for k in range(1, len(f_idx) + 1):
        if k == len(f_idx) or f_idx[k] - f_idx[k - 1] > 1:
            groups.append(np.arange(start, k))
            start = k
    return groups


def residual_map(case, problem, z, fit, held, sig_fit, sig_held):
    """Mean squared normalised residual per channel and fitted window, and on the held-out
    points within 3 window widths of it; returns (cells, fitted residuals, held-out ones)."""
    rf = normalised(problem, z, case, fit, sig_fit)
    rh = normalised(problem, z, case, held, sig_held)
    cells = []
    for b, g in enumerate(window_bands(fit)):
        lo, hi = case.f[fit[g[0]]], case.f[fit[g[-1]]]
        width = hi - lo
        near = (case.f[held] >= lo - 3 * width) & (case.f[held] <= hi + 3 * width)
        for c, ch in enumerate(case.channels):
            cells.append({"channel": ch.name, "band_hz": [float(lo), float(hi)],
                          "fitted": float(np.mean(rf[c, g] ** 2)),
                          "held_out": float(np.mean(rh[c, near] ** 2)) if near.any() else None})
    return cells, rf, rh
