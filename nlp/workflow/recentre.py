"""A re-centred reduced basis: refit until the basis follows the fitted parameters.

The reduced backend (:mod:`nlp.frf.backends.reduced`) projects the model on a basis
of modes and static vectors computed at one parameter point. Computed at the
nominal model it cannot follow a structure whose stiffnesses moved by 10-15 %, and
the fit is biased. Here the basis is recomputed at the current estimate theta_k
(modes of K(theta_k), M(theta_k), Eqns 23-24, plus static and residual-flexibility
vectors), the small projected problem rebuilt and refitted from theta_k:

    theta_{k+1} = argmin f(theta; Psi(theta_k))

until every free variable moves less than ``tol`` of its standard error (Gauss-
Newton, :func:`nlp.solve.identify.standard_errors`) or after ``passes`` passes. At the
fixed point the basis holds the model's own modes at the fit, so the reduced FRF is
close to exact there; the final fit is then checked against the exact sparse FRF
(:func:`nlp.case.assemble.reduced_error`) and refused when the error exceeds the data noise.
"""


import numpy as np

from nlp.case.assemble import build_problem, reduced_error
from nlp.solve.identify import standard_errors

__all__ = ["recentre"]


def recentre(case, problem, best, log=print, passes=4, tol=0.1):
    """Re-centre the reduced basis on the fit and refit, until it stops moving.

    Parameters
    ----------
    case : nlp.case.assemble.Case
    problem : nlp.solve.problem.UpdatingProblem
        The reduced problem the search ran on (its basis at ``centre`` z).
    best : nlp.solve.problem.LocalResult
        The search's best solve.
    passes : int
        At most this many re-centred refits.
    tol : float
        Stop when max_i |z_i(k+1) - z_i(k)| / SE_i < tol.

    Returns
    -------
    problem : UpdatingProblem
        The reduced problem of the last basis.
    best : LocalResult
        The last refit.
    info : dict
        ``passes``: per pass {seconds (local solve) [s], iterations, f, max_move_se,
        vectors} (a pass's basis is not compared with the exact FRF; the last one is);
        ``converged`` (bool);
        ``final_check``: reduced vs exact FRF at the final parameters
        (:func:`nlp.case.assemble.reduced_error`).
    """
    rows = []
    z = best.z
    converged = False
    for k in range(passes):
        new = build_problem(case, centre=z, check=False)  # the last basis is checked below
        res = new.solve(z, prefit=False)  # from the previous basis's optimum
        r, J = new.residuals(res.z)
        cov, _, _ = standard_errors(J, r, new.n_used, new.constraint_jacobian())
        se = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
        move = float(np.max(np.abs(res.z - z) / se))
        rows.append({"pass": k + 1, "seconds": res.seconds, "iterations": res.iterations,
                     "status": res.status, "f": res.f, "max_move_se": move,
                     "vectors": new.reduced_info["vectors"]})
        log(f"re-centred basis, pass {k + 1}: {new.reduced_info['vectors']} vectors, local solve "
            f"{res.seconds:.1f} s ({res.iterations} iterations, {res.status}), f {res.f:.6g}, "
            f"largest move {move:.3g} standard errors")
        problem, best, z = new, res, res.z
        if move < tol:
            converged = True
            break
    final = reduced_error(case, problem.evaluator, z)
    log(f"reduced vs exact FRF at the final parameters: RMS ln|H| error {final['rms_log_error']:.2g}"
        f" (max {final['max_log_error']:.2g}) vs noise {final['noise']:.2g} at "
        f"{final['points_checked']} of the case's frequencies")
    problem.reduced_info = dict(final, recentred=True)
    return problem, best, {"passes": rows, "converged": converged, "final_check": final}
