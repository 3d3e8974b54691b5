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
from nlp.frf.backends.reduced import enrich
from nlp.frf.backends.system import LinearSystem
from nlp.diagnosis.locations import is_fe, rigid_translation
from nlp.solve.identify import standard_errors

__all__ = ["uses_reduced", "basis_of", "recentre_baseline", "PASSES", "UNION_PASSES", "TOL_SE"]

# a budget, not a decision: each pass is one local solve, and where the basis converges the
# fixed point's moves shrink by about an order of magnitude per pass, so five passes take a
# move of hundreds of standard errors below TOL_SE; one that does not settle is reported
PASSES = 5
UNION_PASSES = 2   # then passes on one basis spanning several centres (a budget too)
TOL_SE = 0.1   # stop when no parameter moves by more than this many standard errors
_BASES = {}    # (id(model), centre bytes) -> (model, basis): the model is kept, so its id is not reused


def uses_reduced(case):
    """Does the case ask for the reduced backend (``model.frf_backend: reduced``)?"""
    return case.config.model.frf_backend == "reduced"


def basis_of(case):
    """The reduced basis at the case's ``basis_centre`` (default: its initial z); a centre of
    several rows (k, n_z) gives one basis spanning the bases at each (``reduced.enrich``).
    It also spans the supports' rigid translation (a flexible base moves them by it)."""
    z = case.params.z0 if case.basis_centre is None else np.asarray(case.basis_centre, float)
    key = (id(case.model), z.shape, z.tobytes())
    if key not in _BASES or _BASES[key][0] is not case.model:
        while len(_BASES) >= 2:
            _BASES.pop(next(iter(_BASES)))
        system = LinearSystem.from_model(case.model, case.damping, case.target)
        centres = [z] if z.ndim == 1 else list(z)
        bases = [reduced_basis_at(case, c, check=False)[0] for c in centres]
        # a flexible base carries every support by r (families.BaseFlexibility), which
        # fixed-base modes and static vectors do not span: on the 2,100-DOF frame with
        # planted flexible supports, the family at the true values fitted at reduced
        # chi-square 467 without r in the basis and 1.04 with it (basis at the truth)
        bases.append(_support_translation(case)[:, None])
        psi = enrich(system, bases)
        _BASES[key] = (case.model, psi)
    return _BASES[key][1]


def _support_translation(case):
    """The rigid translation a flexible base moves the model by: r of an FE model
    (:func:`nlp.diagnosis.locations.rigid_translation`), 1 on every row of a chain."""
    if is_fe(case.model):
        return rigid_translation(case.model, case.target.ground_r)
    return np.ones(case.model.n)


def recentre_baseline(case, refit, z, log):
    """(case with basis_centre, its centre, z, info): refit the baseline on bases centred on its
    optimum until no parameter moves by TOL_SE standard errors (at most PASSES), then
    check the last basis against the exact FRF there (refused beyond the data noise).

    refit(case, z) -> (problem, LocalResult) fits the case's own model from z.
    """
    n_z = case.params.n_z
    pr, moves = None, []

    def one_pass(case, z, centre, words):
        case = replace(case, basis_centre=np.array(centre, float))
        pr, res = refit(case, z)
        r, J = pr.residuals(res.z)
        cov, _, _ = standard_errors(J, r, pr.n_used, pr.constraint_jacobian())
        se = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        moves.append(float(np.max(np.abs(res.z - z) / se)))
        log(f"{words}: largest move {moves[-1]:.3g} standard errors, f {res.f:.6g}")
        return case, pr, res.z

    for _ in range(PASSES):
        case, pr, z = one_pass(case, z, z[:n_z], "reduced basis re-centred on the baseline")
        if moves[-1] < TOL_SE:
            break
    else:
        # the optimum swings between centres (weakly determined directions move it far, and
        # a basis is accurate only near its centre): one basis spanning the last centres, the
        # optimum and the nominal model is accurate along the whole swing
        centres = [z[:n_z], case.basis_centre, case.params.z0[:n_z]]
        for _ in range(UNION_PASSES):
            case, pr, z = one_pass(case, z, centres, f"basis spanning {len(centres)} centres "
                                   f"(the swing of the last passes and the nominal model)")
            if moves[-1] < TOL_SE:
                break
            centres = [z[:n_z]] + centres
        else:
            log(f"warning: the reduced basis did not settle in {PASSES} + {UNION_PASSES} "
                f"passes (last move {moves[-1]:.3g} standard errors): the baseline depends "
                f"on the basis by that much")
    check = reduced_error(case, pr.evaluator, z[:n_z]) if pr.params.n_z == n_z else None
    if check is not None:
        log(f"reduced vs exact FRF at the baseline: RMS ln|H| error {check['rms_log_error']:.2g} "
            f"vs noise {check['noise']:.2g} at {check['points_checked']} frequencies")
    return case, case.basis_centre, z, {"moves_se": moves, "check": check}
