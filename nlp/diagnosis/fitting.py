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
from nlp.diagnosis.families import extend_parameters, references
from nlp.solve.problem import SolverConfig, Target, UpdatingProblem
from nlp.solve.search import scatter_search
from nlp.diagnosis.evidence import quasi_covariance


# ---------------------------------------------------------------------- noise
def noise_sigma(case, idx):
    """Standard deviation of ln|H| at points idx of every channel: (n_ch, len(idx)),
    per frequency, from the noise model of the case's FRF route (nlp/noise.py)."""
    return sigma_ln(case, idx)


# ------------------------------------------------------------------ problems
def _target(case, idx, sigma):
    tg = case.target
    return Target(omega=2 * np.pi * case.f[idx], H=case.H[:, idx], weight=1.0 / sigma,
                  channels=tg.channels, excitation=tg.excitation, force_dof=tg.force_dof,
                  ground_r=tg.ground_r, kernel=tg.kernel)


def _problem(case, target, enrichments=(), values=None, compile=True, optimize=True,
             damping=None, max_iter=None, residual=None):
    """The updating NLP; optimize=False compiles quicker, slower-running C (a refit).

    damping : optional (damping model, its ParameterSet) in place of the case's (the
    structured damping refit); the added physics keeps the case's reference values.
    max_iter : optional cap on the solver's iterations (below the case's own); a capped
        problem is not finished by Newton steps where it stops (nlp/polish.py).
    residual : optional residual form in place of the case's (the loss check's complex refit).
    """
    cfg = case.config
    refs = _refs(case)
    damping, base_params = damping if damping is not None else (case.damping, case.params)
    params = extend_parameters(base_params, enrichments, refs, values)
    options = dict(cfg.solver.options)
    if max_iter is not None:
        key = "ipopt.max_iter" if "ipopt.max_iter" in options else "max_iter"
        options[key] = min(int(options.get(key, max_iter)), max_iter)
    solver = SolverConfig(cfg.solver.name, options, compile, optimize)
    if residual is None:
        residual = "complex" if cfg.objective.residual == "complex" else "log_magnitude"
    pr = UpdatingProblem(case.model, damping, params, target, residual=residual,
                         solver=solver, total_mass=cfg.parameters.total_mass,
                         enrichments=enrichments, refs=refs)
    # a capped refit bounds its optimum and is continued when adopted (_continue_refit);
    # Newton steps from wherever each of its starts stopped cost more than the cap saves
    # (retired 832173/44: minutes per round on a 2,700-residual, 27-parameter refit)
    pr.polish_unconverged = max_iter is None
    return pr


def _normalised(problem, z, case, idx, sigma):
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


def _search(problem, config, setup=None):
    """Scatter search; (best result, converged). When no start converged (a solver that
    crawls along a weakly determined direction until its iteration limit), the lowest
    objective reached is used, as every f is a true evaluation at a feasible point, and
    converged is False (diagnosis.json says so)."""
    from nlp.errors import SearchFailed
    kept = _Kept()
    try:
        return scatter_search(problem, config, progress=None, checkpoint=kept,
                              setup=setup).best, True
    except SearchFailed:
        finite = [r for r in kept.results.values() if np.isfinite(r.f)]
        if not finite:
            raise
        return min(finite, key=lambda r: r.f), False


def _fit(problem, z0_list):
    best = None
    for z0 in z0_list:
        r = problem.solve(z0)
        if best is None or r.f < best.f:
            best = r
    return best


def _refs(case):
    return references(case.model, getattr(case.damping, "C0", np.eye(case.model.n)))


def _signed(problem, z, case, idx, sigma):
    """Signed residuals over noise, the objective's own (nlp/problem.py): (n_ch, n) of
    ln|Ha/Hx| / sigma, or with the phase (2 n_ch, n) of the real and imaginary parts of
    (Ha - Hx) / |Hx| / sigma. Their sum of squares is the chi-square (2 x objective)."""
    Ha = problem.channel_frfs(z, 2 * np.pi * case.f[idx])
    Hx = case.H[:, idx]
    if case.config.objective.residual == "complex":
        d = (Ha - Hx) / np.abs(Hx) / sigma
        return np.vstack([d.real, d.imag])
    return np.log(np.abs(Ha / Hx)) / sigma


def _quasi_se(pr, z, free=None):
    """Standard errors of theta at z, inflated by the remaining misfit (quasi-likelihood).

    free : optional boolean mask of the decision variables the solve left free (the
    others held by its bounds carry no error).
    """
    free = np.ones(pr.params.n_z, bool) if free is None else np.asarray(free, bool)
    r, J = pr.residuals(z)
    G = pr.constraint_jacobian()
    G = G[:, free] if G.size else G
    cov, _ = quasi_covariance(J[:, free], r, max(pr.n_used - int(free.sum()) + G.shape[0], 1), G)
    T = pr.params.T[:, free]
    return np.sqrt(np.clip(np.diag(T @ cov @ T.T), 0, None)), cov


def _windows(cfg, case, mult):
    """Points within mult x k half-power bandwidths of the peaks."""
    if mult == 1:
        return case.selected
    c = replace(cfg, frequencies=replace(cfg.frequencies, k=mult * cfg.frequencies.k))
    idx = np.asarray(half_power_points(c, case.f, case.H, case.channels, case.target.excitation,
                                 case.coherence, case.noise.detect), int)
    return idx[case.f[idx] > 0]
