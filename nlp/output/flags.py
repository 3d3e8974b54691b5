"""Honest flags: results that look fine in a table but must not be read as fine.

Each flag is a dict ``{"kind", "subject", "message", "advice"}`` stored under
``"flags"`` in result.json / summary.json, printed as a warning and shown at
the top of report.html.

* ``at_bound``: a parameter on (or within 0.1 % of the range from) a bound. The
  optimum is not interior, so its Gauss-Newton standard error does not hold;
  it means the bound is wrong, the model is wrong, or the data do not identify
  the parameter.
* ``iteration_limit``: the best start stopped at the solver's iteration (or
  time) limit, or a start that did reached a lower objective than the best
  converged one: the optimum may not be reached.
* ``single_start``: only one of several finished starts reached the best
  objective. The objective has several minima and the search found the lowest
  once: a lower one may exist that no start reached.
* ``misfit_above_noise``: the updated model misses the data by far more than
  the data's own noise (from the FRF's scatter, coherence or rest portions,
  :mod:`nlp.frf.noise`): either the search ended in a local minimum or the
  model lacks physics the data show. Parameters and standard errors of such a
  fit describe the best compromise, not the structure.
* ``undetermined``: some combinations of the relative parameters have a standard
  error above 100 %: a whole change along them moves the chi-square by less than 1,
  so the data cannot tell them from zero or from twice their value, and the values
  along them are the start's, not the data's (many per-storey parameters, few sensors).
* ``negative_correlation``: a replayed time history anti-correlates with its
  record, the signature of a sign or unit error (an inverted sensor, a force
  taken with the wrong sign, a displacement given as acceleration).
"""

import numpy as np

from nlp.solve.stopping import LIMIT_STATUSES

__all__ = ["AT_BOUND", "MISFIT_RATIO", "UNDETERMINED_SE", "bound_flag", "iteration_flag",
           "single_start_flag", "misfit_flag", "undetermined_flag", "replay_flags"]

AT_BOUND = 1e-3   # distance to a bound, as a fraction of the bound interval, that counts as "on"
# RMS of ln|H_a / H_x| over the noise's RMS above which the fit is flagged (a reduced
# chi-square of 2.25). At the truth the ratio is 1 within sqrt(1 / (2 N)) (chi-square
# sampling: 0.07 at N = 100 points); the noise estimated from the FRF's own scatter
# (nlp.frf.noise) came out 1.00x the true noise on the four-storey case and 1.05-1.25x on
# the tall frames of scripts/bench_scale.py, so a fit at its noise floor stays below 1.3.
MISFIT_RATIO = 1.5
# Standard error, in relative-change units, of a unit combination of the relative
# parameters above which it is not determined: 1 is a 100 % change, which moves the
# chi-square by (1 / SE)^2 < 1 along it (the Gauss-Newton covariance is s^2 (J^T J)^-1,
# so SE > 1 is an eigenvalue of J^T J below s^2: nlp.solve.lm's undetermined directions)
UNDETERMINED_SE = 1.0


def bound_flag(name, value, lower, upper, unit, se_key):
    """The at-bound flag of one parameter (physical value and bounds), or None.

    se_key : the case-file keys that set this bound, named in the advice.
    """
    span = upper - lower
    if not np.isfinite(span) or span <= 0:
        return None
    side = ("lower" if value - lower <= AT_BOUND * span else
            "upper" if upper - value <= AT_BOUND * span else None)
    if side is None:
        return None
    b = lower if side == "lower" else upper
    return {"kind": "at_bound", "subject": name, "bound": side,
            "message": f"{name} = {value:.6g} {unit} is on its {side} bound {b:.6g} {unit}; "
                       "its standard error does not apply (the optimum is not interior)",
            "advice": f"either the bound is wrong (widen {se_key}), the model is wrong (the data "
                      "ask for a value the model can only approach at the bound; try "
                      "'frf-nlp diagnose'), or these data do not identify it (check "
                      "identifiability.weak_directions)"}


def iteration_flag(best, results, solver, agreed=0):
    """Flag a search whose answer may lie beyond a solver limit, or None.

    The best start is flagged when it stopped at an iteration or time limit
    itself (it is the best only when ``agreed`` >= 3 starts reached the same
    objective, :func:`nlp.solve.search.agreed_minimum`), or when a start that stopped
    at a limit had already reached a lower objective: that start was still
    descending where the best one is reported.
    """
    key = "ipopt.max_iter" if solver == "ipopt" else "max_iter"
    advice = (f"raise solver.options.{key}, run more starts (--starts), and if it persists "
              "look for a weakly identified combination (identifiability) or a wrong model")
    if best.status in LIMIT_STATUSES:
        msg = (f"the best start stopped at the solver's limit ({best.status}, "
               f"{best.iterations} iterations): it may not be at an optimum")
        if agreed:
            msg = (f"no start met the solver's tolerance: the best stopped at its limit "
                   f"({best.status}, {best.iterations} iterations), where {agreed} independent "
                   "starts reach the same objective (within 0.1 in chi-square); the objective's minimum is "
                   "reached, but parameters along weakly identified combinations are not "
                   "determined (their spread over those starts is in the result)")
        return {"kind": "iteration_limit", "subject": "best start", "message": msg,
                "advice": advice}
    lower = [r for r in results if r.status in LIMIT_STATUSES and np.isfinite(r.f)
             and r.f < best.f]
    if not lower:
        return None
    r = min(lower, key=lambda r: r.f)
    return {"kind": "iteration_limit", "subject": "search",
            "message": f"{len(lower)} start(s) stopped at the solver's limit ({r.status}, "
                       f"{r.iterations} iterations) below the best converged objective "
                       f"({r.f:.6g} < {best.f:.6g}): the optimum may lie elsewhere",
            "advice": advice}


def single_start_flag(n_near, n_finished, rel_tol):
    """Flag a search whose best objective only one start reached, or None.

    n_near : converged starts within rel_tol of the best; n_finished : converged starts.
    """
    if n_finished < 2 or n_near != 1:
        return None
    return {"kind": "single_start", "subject": "search",
            "message": f"only 1 of {n_finished} converged starts reached the best objective "
                       f"(within {rel_tol:.0%}): the objective has several minima, and a lower "
                       "one may exist that no start reached",
            "advice": "run more starts (--starts); if the best still stands alone and its "
                      "misfit is above the noise, fit fewer parameters (tie stories in groups) "
                      "or add data that separate them (more sensors, another input point)"}


def misfit_flag(rms_misfit, rms_noise, n_points):
    """Flag a fit whose RMS ln|H_a / H_x| exceeds MISFIT_RATIO times the noise's, or None.

    rms_misfit, rms_noise : RMS over the fitted points of ln|H_a / H_x| and of the
    noise's standard deviation of ln|H|; n_points : the fitted points.
    """
    if not (np.isfinite(rms_misfit) and np.isfinite(rms_noise) and rms_noise > 0):
        return None
    ratio = rms_misfit / rms_noise
    if ratio <= MISFIT_RATIO:
        return None
    return {"kind": "misfit_above_noise", "subject": "fit", "ratio": float(ratio),
            "message": f"the updated model misses the data by {ratio:.1f} times their noise "
                       f"(RMS ln|H| error {rms_misfit:.3g} against noise {rms_noise:.3g} over "
                       f"{n_points} points): a local minimum or missing physics, and the "
                       "standard errors do not hold",
            "advice": "run more starts (--starts) and compare their objectives; if they agree, "
                      "the model lacks physics the data show: run 'frf-nlp diagnose'"}


def undetermined_flag(cov, names, values):
    """Flag the combinations of relative parameters that the data do not determine, or None.

    cov : (n, n) covariance of the free relative parameters (theta: 1 is a 100 % change);
    names : their names; values : their relative changes theta at the optimum (a
    parameter's value is nominal x (1 + theta), so its relative standard error is
    SE(theta) / (1 + theta)).
    """
    cov = np.asarray(cov, float)
    if cov.size == 0:
        return None
    lam, V = np.linalg.eigh(0.5 * (cov + cov.T))
    weak = lam > UNDETERMINED_SE ** 2
    if not weak.any():
        return None
    se = np.sqrt(np.clip(np.diag(cov), 0, None)) / np.maximum(1 + np.asarray(values, float), 1e-12)
    loose = [n for n, x in zip(names, se) if x > UNDETERMINED_SE]
    # the parameters that make up the undetermined combinations, largest share first
    share = np.sum(V[:, weak] ** 2, axis=1)
    top = [names[i] for i in np.argsort(-share)[:6] if share[i] > 0.05]
    return {"kind": "undetermined", "subject": "parameters", "combinations": int(weak.sum()),
            "parameters_above_100_percent": loose,
            "message": f"{int(weak.sum())} of {len(names)} combinations of the parameters are not "
                       "determined by these data (standard error above 100 %: a whole change "
                       "along them moves the misfit by less than its noise)"
                       + (f", mostly {', '.join(top)}" if top else "")
                       + f"; {len(loose)} parameter(s) have a standard error above their own "
                       "value. Along those combinations the values are set by the start and "
                       "the solver, not by the data",
            "advice": "fit fewer parameters (tie storeys or elements in groups: parameters.tie), "
                      "fix the ones known from drawings, or add data that separate them "
                      "(sensors on the floors in between, another input point)"}


def replay_flags(time_domain):
    """Flags for replayed channels whose correlation with the record is negative."""
    out = []
    for name, rep in time_domain.items():
        r = rep["correlation"]
        if np.isfinite(r) and r < 0:
            out.append({"kind": "negative_correlation", "subject": name,
                        "message": f"the replayed {rep['quantity']} of {name} anti-correlates "
                                   f"with its record (correlation {r:.3f})",
                        "advice": "likely a sign or unit error: check the sensor's orientation, "
                                  "its quantity and unit in data.channels, and the sign of the "
                                  "input"})
    return out
