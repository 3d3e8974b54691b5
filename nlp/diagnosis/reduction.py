"""Diagnosis on the reduced backend: one basis per centre, re-centred on the baseline.

A case whose model asks for the reduced backend (``model.frf_backend: reduced``, a
large FE model) is diagnosed on it too: every fit of the diagnosis, with or without
added physics, runs on the same fixed basis (:mod:`nlp.frf.backends.reduced`; the
families' terms are projected on it, their extra DOFs kept, :mod:`nlp.frf.backends.terms`).
A basis computed at the nominal model biases the fit of a structure whose stiffnesses
moved (:mod:`nlp.workflow.recentre`), and that bias would be read as missing physics, so
the baseline is refitted on a basis re-centred on its own optimum until it stops moving,
and that basis is compared with the exact FRF there before any candidate is judged.
"""

from dataclasses import replace

import numpy as np

from nlp.case.assemble import reduced_basis_at, reduced_error
from nlp.solve.identify import standard_errors

__all__ = ["uses_reduced", "basis_of", "recentre_baseline", "PASSES", "TOL_SE"]

# a budget, not a decision: each pass is one local solve, and where the basis converges the
# fixed point's moves shrink by about an order of magnitude per pass, so five passes take a
# move of hundreds of standard errors below TOL_SE; one that does not settle is reported
PASSES = 5
TOL_SE = 0.1   # stop when no parameter moves by more than this many standard errors
_BASES = {}    # (id(model), centre bytes) -> (model, basis): the model is kept, so its id is not reused


def uses_reduced(case):
    """Does the case ask for the reduced backend (``model.frf_backend: reduced``)?"""
    return case.config.model.frf_backend == "reduced"


def basis_of(case):
    """The reduced basis at the case's ``basis_centre`` (default: its initial z)."""
    z = case.params.z0 if case.basis_centre is None else np.asarray(case.basis_centre, float)
    key = (id(case.model), z.tobytes())
    if key not in _BASES or _BASES[key][0] is not case.model:
        while len(_BASES) >= 2:
            _BASES.pop(next(iter(_BASES)))
        _BASES[key] = (case.model, reduced_basis_at(case, z, check=False)[0])
    return _BASES[key][1]


def recentre_baseline(case, refit, z, log):
    """(case with basis_centre, its centre, z, info): refit the baseline on bases centred on its
    optimum until no parameter moves by TOL_SE standard errors (at most PASSES), then
    check the last basis against the exact FRF there (refused beyond the data noise).

    refit(case, z) -> (problem, LocalResult) fits the case's own model from z.
    """
    n_z = case.params.n_z
    pr, moves = None, []
    for _ in range(PASSES):
        case = replace(case, basis_centre=np.array(z[:n_z], float))
        pr, res = refit(case, z)
        r, J = pr.residuals(res.z)
        cov, _, _ = standard_errors(J, r, pr.n_used, pr.constraint_jacobian())
        se = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        moves.append(float(np.max(np.abs(res.z - z) / se)))
        z = res.z
        log(f"reduced basis re-centred on the baseline: largest move {moves[-1]:.3g} "
            f"standard errors, f {res.f:.6g}")
        if moves[-1] < TOL_SE:
            break
    else:
        log(f"warning: the reduced basis did not settle in {PASSES} passes (last move "
            f"{moves[-1]:.3g} standard errors): the baseline depends on the basis by that much")
    check = reduced_error(case, pr.evaluator, z[:n_z]) if pr.params.n_z == n_z else None
    if check is not None:
        log(f"reduced vs exact FRF at the baseline: RMS ln|H| error {check['rms_log_error']:.2g} "
            f"vs noise {check['noise']:.2g} at {check['points_checked']} frequencies")
    return case, case.basis_centre, z, {"moves_se": moves, "check": check}
