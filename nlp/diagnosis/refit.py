"""Candidate refits: the current model plus one candidate, fitted with the same NLP.

A refit starts at the current optimum with the candidate's parameters added (at the
family's guess and at seeded points of their box), is capped at REFIT_ITER iterations, and
is continued to the case's own limit when its candidate is adopted. Also here: the
re-solve of the current model from the refits' optima (repolish) and the backward
elimination of findings the others make unnecessary (prune).
"""

from dataclasses import replace
import math

import numpy as np

from nlp.diagnosis.evidence import BIC_ACCEPT, dispersion
from nlp.diagnosis.fitting import (best_fit, diagnosis_problem, case_references, normalised,
                                   projected_columns, quasi_se, with_values)
from nlp.diagnosis.locations import located
from nlp.diagnosis.resolution import appendage_split, case_resolution, resolved
from nlp.diagnosis.spread import correlation_factor
from nlp.output.progress import stage
from nlp.solve.executors import Setup, make_executor

# Iterations of a candidate refit. It starts at the current optimum with one family added:
# the candidate that explains the data converges in tens of iterations (measured: the true
# coupling of a benchmark case in 39-100 iterations, 0.2 s), while wrong ones under a large
# misfit crawl to the case's max_iter without nearing a stationary point (3,000 iterations,
# 19 s a start, 14 min a round; see docs/method/diagnosis.md). A refit that stops short
# only bounds its optimum: its evidence is understated, never overstated; a finding
# adopted from one is continued to the case's own max_iter (continue_refit).
REFIT_ITER = 300
REPOLISH_MIN = 1.0     # scaled chi-square (over phi) a re-solved current model must gain to replace it
MAX_REPOLISH = 2       # re-solves of the current model per diagnosis (each repeats a round)


def refit(case, target, current, z_cur, e, score, n_fit, held, sig_held, box=True):
    """Fit the current model plus candidate e: values, quasi-likelihood errors, chi-squares.

    box=False leaves out the two seeded starts spread over the candidate's box: for a
    question about one place in it (does an appendage tuned to this resonance explain it,
    nlp.diagnosis.discrepancy.explained_by), where they only look elsewhere.
    """
    refs = case_references(case)
    # 3-5 solves: gcc -O2 would take longer than they do (same numbers at -O0)
    pr = diagnosis_problem(case, target, current + [e], optimize=False, max_iter=REFIT_ITER)
    k = len(e.names)
    sp = e.spec(refs)
    # start the added parameters inside their box, not on a zero bound
    start = [max(v, lo_ + 0.5 * sc) if v <= lo_ else v
             for v, lo_, sc in zip(sp["initial"], sp["lower"], sp["scale"])]
    # the added parameters start at the family's guess and at two seeded points of their box
    rng = np.random.default_rng(len(current) * 7919 + sum(map(ord, repr(e))))
    spread = [[lo_ + (hi_ - lo_) * rng.uniform(0.05, 0.6) for lo_, hi_ in zip(sp["lower"], sp["upper"])]
              for _ in range(2)] if box else []
    extra = e.starts(refs) if hasattr(e, "starts") else []
    res = best_fit(pr, [with_values(pr, z_cur, v) for v in [start] + extra + spread])
    # a refit that ends above the current optimum with the candidate at its null has failed
    # (a coupling refit has ended hundreds of thousands in BIC above its baseline, and was
    # read as evidence against it; see docs/method/diagnosis.md): the candidate's best
    # point is then its null
    z_null = with_values(pr, z_cur, [max(v, lo_) for v, lo_ in zip(sp["null"], sp["lower"])])
    f_null = float(pr.objective(z_null))
    if not np.isfinite(res.f) or res.f > f_null:
        res = replace(res, z=z_null, f=f_null, success=False)
    theta_e = pr.theta(res.z)[-k:]
    on_bound = [n for n, t, lo_, hi_, sc in zip(e.names, theta_e, sp["lower"], sp["upper"],
                                                sp["scale"])
                if any(abs(t - b) <= 1e-5 * max(abs(sc), 1e-12) for b in (lo_, hi_) if b != 0.0)]
    at_bound = bool(on_bound)
    rh = normalised(pr, res.z, case, held, sig_held)
    rj = pr.residuals(res.z)
    se = quasi_se(pr, res.z, rj=rj)[0][-k:]
    return {"physics": e.family, "location": located(case, e), "enrichment": e,
            "parameters": dict(zip(e.names, map(float, theta_e))),
            "uncertainty": dict(zip(e.names, map(float, se))),
            "score": score, "chi2": 2 * res.f, "held_out": float(np.mean(rh ** 2)),
            "correlation_factor": _correlation(case, target, pr, rj, k),
            "at_bound": at_bound, "on_bound": on_bound, "converged": bool(res.success),
            "z": res.z, "problem": pr,
            "split": appendage_resolution(case, pr, res.z) if e.family == "secondary_oscillator" else None}


def _correlation(case, target, pr, rj, k):
    """The candidate's correlation factor at its optimum (nlp.diagnosis.spread; rj: the
    residuals and Jacobian there): how much the residuals' correlation inflates its
    chi-square drop. Recorded, not yet decided on (docs/method/diagnosis.md, section 4)."""
    r, J = rj
    _, _, Jp = projected_columns(pr, J, k)
    f = target.omega / (2 * np.pi)
    idx = np.clip(np.searchsorted(case.f, f), 0, case.f.size - 1)
    return correlation_factor(r, Jp, idx)


def continue_refit(r, case, held, sig_held, log):
    """Continue an adopted refit that stopped at REFIT_ITER, with the case's own iteration
    limit, from where it stopped; its values, errors and chi-squares follow."""
    pr = r["problem"]
    res = pr.solve(r["z"])
    if np.isfinite(res.f) and 2 * res.f <= r["chi2"]:
        k = len(r["parameters"])
        names = list(r["parameters"])
        r["z"], r["chi2"], r["converged"] = res.z, 2 * res.f, bool(res.success)
        r["parameters"] = dict(zip(names, map(float, pr.theta(res.z)[-k:])))
        r["uncertainty"] = dict(zip(names, map(float, quasi_se(pr, res.z)[0][-k:])))
        r["held_out"] = float(np.mean(normalised(pr, res.z, case, held, sig_held) ** 2))
    log(f"    {r['physics']} {r['location']}: refit continued to chi-square {r['chi2']:.1f}"
        + ("" if r["converged"] else " (still not converged: its values are not at a stationary point)"))


def appendage_resolution(case, pr, z):
    """How far the fitted appendage's mode stands from the nearest structural mode, against
    what the data can resolve (nlp/diagnosis/resolution.py)."""
    sep, half, fa, fb = appendage_split(*pr.system_matrices(z))
    res_hz = case_resolution(case)
    return {"separation_hz": sep, "half_widths_hz": half, "resolution_hz": res_hz,
            "appendage_mode_hz": fa, "nearest_mode_hz": fb, "resolved": resolved(sep, half, res_hz)}


def _refit_one(jobs, i):
    """One refit in a worker: the result without its NLP (CasADi functions do not
    pickle; the parent rebuilds the one it keeps)."""
    r = refit(*jobs[i])
    r["problem"] = None
    return r


def _jobs(jobs):
    return jobs


def refit_all(jobs, search):
    """Refit independent candidates on the case's executor (nlp/executors): forked
    local workers, which inherit the jobs, or a Dask cluster, which receives them
    pickled (cases and candidates pickle; each worker builds its NLPs).

    The results do not depend on the executor or the number of workers: each
    refit is deterministic and they are returned in the order of the jobs.
    """
    workers = max(1, min(int(search.workers or 1), len(jobs)))
    out = {}
    with stage("candidate refits", total=len(jobs), unit="refit") as bar:
        if workers == 1 and search.executor != "dask":
            for i, j in enumerate(jobs):
                out[i] = refit(*j)
                bar.update()
        else:
            with make_executor(search.executor, workers=workers,
                               scheduler=search.scheduler) as ex:
                stream = ex.stream(Setup(_jobs, jobs, value=jobs), _refit_one,
                                   [(i, i) for i in range(len(jobs))])
                try:
                    for i, r in stream:  # in completion order; returned in job order
                        out[i] = r
                        bar.update()
                finally:
                    stream.close()
    return [out[i] for i in range(len(jobs))]


def repolish(state, results, case, held, sig_held, n_fit):
    """The current model re-solved from the refits' optima with their candidate removed.

    A refit starts from the current optimum with one more parameter, which opens a
    path out of a local minimum; when it then lands far below, the current model
    alone may reach that basin too (a baseline stuck at a reduced chi-square in the
    hundreds has been "explained" by candidates at their null values; see
    docs/method/diagnosis.md). Returns the new state when a re-solve gains more than
    REPOLISH_MIN in chi-square scaled by the current model's dispersion phi (n_fit fitted
    residuals), the unit every candidate is judged in, else None: on a misfit 200 times the
    noise a gain of 10 in chi-square repeated a whole round of a 2,100-DOF model's refits.
    """
    pr = state["problem"]
    nz = pr.params.n_z
    gain = REPOLISH_MIN * dispersion(state["chi"], n_fit - nz)
    best = None
    for r in sorted(results, key=lambda r: r["chi2"])[:3]:
        if r["chi2"] >= state["chi"] - gain:
            break
        res = pr.solve(np.asarray(r["z"])[:nz])
        if np.isfinite(res.f) and 2 * res.f < state["chi"] - gain \
                and (best is None or res.f < best.f):
            best = res
    if best is None:
        return None
    rh = normalised(pr, best.z, case, held, sig_held)
    return {"current": state["current"], "z": best.z, "chi": 2 * best.f,
            "held": float(np.mean(rh ** 2)), "problem": pr, "result": best}


def prune(case, target, found, state, n_fit, held, sig_held, log):
    """Backward elimination: drop a finding that the others make unnecessary (removing
    it costs less than BIC_ACCEPT on the quasi-likelihood scale), then refit what is
    left and report its values."""
    while len(found) > 1:
        best_drop = None
        for r in found:
            keep = [x for x in found if x is not r]
            pr = diagnosis_problem(case, target, [x["enrichment"] for x in keep], optimize=False)
            z = np.concatenate([state["z"][:pr.params.n_z - sum(len(x["parameters"]) for x in keep)]]
                               + [_params_z(pr, x, state) for x in keep])
            res = best_fit(pr, [z])
            phi = dispersion(state["chi"], n_fit - pr.params.n_z - len(r["parameters"]))
            cost = (2 * res.f - state["chi"]) / phi - len(r["parameters"]) * math.log(n_fit)
            if cost < BIC_ACCEPT and (best_drop is None or cost < best_drop[0]):
                best_drop = (cost, r, keep, pr, res)
        if best_drop is None:
            break
        cost, r, keep, pr, res = best_drop
        log(f"  dropped {r['physics']} {r['location']}: the other findings explain it "
            f"(BIC cost {cost:.1f})")
        rh = normalised(pr, res.z, case, held, sig_held)
        state = {"current": [x["enrichment"] for x in keep], "z": res.z, "chi": 2 * res.f,
                 "held": float(np.mean(rh ** 2)), "problem": pr}
        found = keep
    # values and errors of the final set, from its own fit
    pr, z = state["problem"], state["z"]
    theta = pr.theta(z)
    se = quasi_se(pr, z)[0]
    k = pr.params.n_theta - pr.params.n_physics
    for x in found:
        for name in x["parameters"]:
            i = pr.params.names.index(name, k)
            x["parameters"][name] = float(theta[i])
            x["uncertainty"][name] = float(se[i])
    return found, state


def _params_z(pr, finding, state):
    """The decision variables of one finding's parameters at the current optimum."""
    full = state["problem"]
    theta = full.theta(state["z"])
    idx = [full.params.names.index(n) for n in finding["parameters"]]
    scales = [full.params.params[i].scale for i in idx]
    return np.array([theta[i] / s for i, s in zip(idx, scales)])
