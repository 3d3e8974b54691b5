"""Effects inside the model class: they show only in the fitted parameters.

An added mass appears as a floor mass far outside its stated prior; a concentrated
damper as one story dominating the fitted C (decomposed into story dashpots plus a
mass-proportional part, :mod:`.priors`). An ordinary stiffness change is reported and
stays ``adequate``.
"""

import math

import numpy as np

from nlp.case.parameters import dashpot_damping
from nlp.diagnosis.fitting import best_fit, diagnosis_problem, quasi_se
from nlp.diagnosis.priors import (DAMPER_SE, damper_check, decompose_damping, floor_of_mass,
                                  prior_check, prior_sigmas)
from nlp.model.damping import GeneralDamping

# An absorbed added mass is pointed at by its fitted floor mass: more than this relative
# change, 3 standard errors and 2 prior sigmas; an absorbed damper by its story's damping
# per unit stiffness over this multiple of the other stories' median.
ABSORBED_MASS, ABSORBED_MASS_Z, ABSORBED_PRIOR_Z = 0.05, 3, 2
ABSORBED_DAMPER_RATIO = 2


def inside_model_class(cfg, case, state, absorbed, log):
    """Parameters far outside their prior, concentrated dampers in the fitted C, and
    the absorbed candidates that the fitted parameters actually point at."""
    pr, z = state["problem"], state["z"]
    se, _ = quasi_se(pr, z)
    theta = pr.theta(z)
    sigmas = prior_sigmas(cfg.parameters.prior, pr.params)
    outside = prior_check(pr.params, theta, se, sigmas)
    shear = cfg.model.type == "shear_frame"
    findings, changes = _prior_findings(outside, shear)
    decomposition, dampers = _damping_decomposition(case, state, shear, log)
    findings += [_damper_finding(d) for d in dampers]
    ratios = decomposition["story_ratio_c_over_k"] if decomposition else None
    found = [(f["physics"], f["location"]) for f in findings]
    # a hypothesis that is already a finding here would only repeat it
    informative = [h for h in _absorbed_indicated(pr, theta, se, sigmas, ratios, absorbed)
                   if (h["physics"], h["location"]) not in found]
    if outside:
        log("  outside the prior: " + ", ".join(f"{o['parameter']} {o['z_prior']:+.1f} sigma"
                                               for o in outside))
    return {"findings": findings, "parameter_changes": changes, "damping": decomposition,
            "absorbed": informative, "parameters": _parameter_table(pr, theta, se, sigmas)}


def _prior_findings(outside, shear):
    """Floor masses above their prior (added masses, on a shear frame), and the other
    parameters outside their prior (changes of the modelled parameters)."""
    findings, changes = [], []
    for o in outside:
        floor = floor_of_mass(o["parameter"]) if shear and o["group"] == "mass" else None
        dv = o["value"] - o["nominal"]
        ds = o["standard_error"] * o["nominal"]
        if floor is not None and dv > 0:
            findings.append({
                "physics": "added_mass", "location": {"floor": floor},
                "parameters": {f"dm{floor}": dv}, "uncertainty": {f"dm{floor}": ds},
                "evidence": {"source": "prior", "z_prior": o["z_prior"],
                             "relative_change": o["relative_change"]},
                "statement": (f"The mass of floor {floor} comes out at {o['value']:.4g} kg, "
                              f"{100 * o['relative_change']:+.0f} % of its nominal "
                              f"{o['nominal']:.4g} kg ({o['z_prior']:+.1f} prior sigmas): an "
                              f"unmodelled mass of {dv:.3g} +- {ds:.2g} kg at floor {floor}.")})
        else:
            o["statement"] = (f"{o['parameter']} = {o['value']:.5g} "
                              f"({100 * o['relative_change']:+.0f} % of nominal {o['nominal']:.5g}, "
                              f"{o['z_prior']:+.1f} prior sigmas): a change of the modelled "
                              "parameter, not missing physics.")
            changes.append(o)
    return findings, changes


def _damping_decomposition(case, state, shear, log):
    """The fitted general C as a0 M + story dashpots, judged on the structured refit
    beyond the bias its misfit can cause: (decomposition, concentrated dampers)."""
    decomposition, dampers = None, []
    if isinstance(case.damping, GeneralDamping) and shear:
        structured = dashpot_refit(case, state)
        if structured["cov"] is not None:
            decomposition, dampers = damper_check(structured["problem"], structured["z"],
                                                  structured["cov"])
        else:
            decomposition = {"story_ratio_c_over_k": None}
        decomposition["structured_refit"] = {k: structured[k] for k in
                                             ("chi2", "chi2_general", "excess", "limit", "fits")}
        log(f"  damping as a0 M + story dashpots: chi-square {structured['chi2']:.1f} against "
            f"{structured['chi2_general']:.1f} with a general C (scaled excess "
            f"{structured['excess']:.1f}, limit {structured['limit']:.1f}, "
            + ("fits as well" if structured["fits"] else "the general C fits better")
            + ("): dampers judged on it" if structured["cov"] is not None else
               "): the refit failed, no damper is judged"))
        dampers = _beyond_misfit(dampers, structured, log)
    return decomposition, dampers


def _beyond_misfit(dampers, structured, log):
    """The dampers that stand beyond the bias the family's misfit can cause.

    Where the general C fits better, the part of the records only it explains (scaled
    chi-square ``excess``) is signal the story dashpots do not model, and it moves each
    estimate: by at most sqrt(excess) of its standard errors, since a misfit e shifts the
    Gauss-Newton estimate of a^T theta by a^T (J^T J)^-1 J^T e, whose ratio to that
    combination's standard error is at most |P_J e| <= |e| (Cauchy-Schwarz). A damper
    must then stand DAMPER_SE standard errors beyond that bound. Where the family fits
    as well (BIC), the excess is what the general C's extra parameters gain on noise.
    """
    fits = structured["fits"]
    bias = 0.0 if fits else math.sqrt(max(structured["excess"], 0.0))
    kept = []
    for d in dampers:
        z = d["excess"] / max(d["standard_error"], 1e-300)
        d["family_fits"], d["misfit_bias_se"] = fits, bias
        if z > DAMPER_SE + bias:
            kept.append(d)
        else:
            log(f"  story {d['story']}: its dashpot excess at {z:.1f} standard errors is within "
                f"the {bias:.1f} that the story-dashpot family's misfit can cause, plus "
                f"{DAMPER_SE:g}: not named")
    return kept


def _damper_finding(d):
    """A concentrated damper of priors.damper_check as a finding."""
    s = d["story"]
    name = f"c{s - 1}{s}"
    where = "the ground" if s == 1 else f"floor {s - 1}"
    return {"physics": "local_damper", "location": {"between": [s - 1, s]},
            "parameters": {name: d["excess"]}, "uncertainty": {name: d["standard_error"]},
            "evidence": {"source": "damping_decomposition", "ratio_to_other_stories": d["ratio"],
                         "modal_share": d["modal_share"],
                         "story_dashpots_fit_as_well": d.get("family_fits", True)},
            "statement": (f"The fitted damping is concentrated in story {s}: a dashpot of "
                          f"{d['excess']:.3g} +- {d['standard_error']:.2g} N s/m between {where} "
                          f"and floor {s} beyond the share of the other stories "
                          f"({d['ratio']:.1f}x their damping per unit stiffness; as a damping "
                          f"ratio of its story it is {d['story_zeta_ratio']:.1f}x the median modal "
                          f"damping of the structure without it, and it supplies "
                          f"{100 * d['modal_share']:.0f} % of one mode's damping)."
                          + ("" if d.get("family_fits", True) else
                             " A general C fits the records better than story dashpots do, so "
                             "the size is that of the nearest story-dashpot model."))}


def _absorbed_indicated(pr, theta, se, sigmas, ratios, absorbed):
    """Absorbed candidates, kept only where the fitted parameters point at them: a floor
    mass well above nominal, or a story carrying far more damping than the others."""
    names = pr.params.names
    fixed = {p.name for p in pr.params.params if p.fixed}
    informative = []
    for e, kept in absorbed:
        ind = None
        if e.family == "added_mass":
            nm = f"m{e.floor}"
            if nm in names and nm not in fixed:
                i = names.index(nm)
                d, sd = float(theta[i]), float(se[i])
                zp = d / sigmas[nm] if nm in sigmas else None
                if d > ABSORBED_MASS and d > ABSORBED_MASS_Z * sd and (
                        zp is None or zp > ABSORBED_PRIOR_Z):
                    ind = (f"m{e.floor} is {100 * d:+.1f} +- {100 * sd:.1f} % of nominal"
                           + (f" ({zp:+.1f} prior sigmas)" if zp is not None else ""))
        elif e.family == "local_damper" and ratios is not None and e.j == e.i - 1:
            others = np.delete(np.asarray(ratios), e.i - 1)
            ref = float(np.median(others)) if others.size else 0.0
            if ref > 0 and ratios[e.i - 1] > ABSORBED_DAMPER_RATIO * ref:
                ind = (f"story {e.i} carries {ratios[e.i - 1] / ref:.1f}x the damping per unit "
                       "stiffness of the others in the fitted C")
        if ind:
            informative.append({"physics": e.family, "location": e.location,
                                "fraction_left": kept, "indicator": ind})
    return informative


def _parameter_table(pr, theta, se, sigmas):
    """Every free mass and stiffness: value, relative change, error, prior z-score."""
    table = []
    for i, p in enumerate(pr.params.params):
        if p.fixed or p.group not in ("mass", "stiffness"):
            continue
        d, sd, sg = float(theta[i]), float(se[i]), sigmas.get(p.name)
        table.append({"parameter": p.name, "group": p.group, "nominal": p.nominal,
                      "value": p.nominal * (1 + d), "relative_change": d, "standard_error": sd,
                      "prior_sigma": sg, "z_prior": d / sg if sg else None})
    return table


def dashpot_refit(case, state):
    """The current model refitted with C = a0 M + story dashpots
    (:func:`nlp.case.parameters.dashpot_damping`).

    A general C has n (n + 1) / 2 parameters, and a decomposition of its point estimate
    carries all their scatter (on the benchmark, true dampers were missed and null cases'
    random dashpots called dampers; see docs/method/diagnosis.md). When the structured C
    fits as well (its chi-square excess, scaled by the remaining misfit, is below the
    difference in parameters times ln N, as in BIC), its story dashpots are estimated
    directly, with their own errors. Starts: the non-negative decomposition of the
    fitted general C, and Rayleigh.
    """
    pr, z = state["problem"], state["z"]
    damping, params = dashpot_damping(case)
    pd = diagnosis_problem(case, pr.target, state["current"], optimize=False,
                           damping=(damping, params))
    theta = pr.theta(z)
    sa, sb, _ = pr.params.slices()
    M, _, C = pr.matrices(z)
    a0, c, _ = decompose_damping(C, M)
    k0 = np.array([float(np.trace(Kj)) / 2.0 if j else float(Kj[0, 0])   # story stiffness
                   for j, Kj in enumerate(map(_dense_of, damping.K_groups))])
    lo, hi = damping.default_bounds()
    decomposed = np.clip(np.concatenate([[a0 / damping.a0_ref], c / (damping.a1_ref * k0)]),
                         lo + 1e-3, hi - 1e-3)
    starts = []
    for d in (decomposed, np.ones(len(damping.names))):
        t = pd.theta(pd.params.z0)
        t[sa], t[sb] = theta[sa], theta[sb]
        sd = pd.params.slices()[2]
        t[sd] = d
        t[pd.params.physics_slice()] = theta[pr.params.physics_slice()]
        starts.append(pd.params.z_from_theta(t))
    res = best_fit(pd, starts)
    nu = max(pr.n_used - pr.params.n_z, 1)
    phi = max(state["chi"] / nu, 1.0)
    dk = max(pr.params.n_z - pd.params.n_z, 1)
    excess = (2 * res.f - state["chi"]) / phi
    # BIC: the general C must earn its extra parameters (a chi-square test's 99.9 % point
    # would refuse the true structured family for misfit that is not damping: a one-segment
    # ordinary case with Rayleigh plus story dashpots in truth gained about twice that point
    # from 9 more parameters; see docs/method/diagnosis.md)
    limit = dk * math.log(max(pr.n_used, 2))
    solved = bool(res.success and np.isfinite(res.f))
    fits = solved and excess <= limit
    # dampers are judged on the structured refit even where the general C fits better: on
    # lab records the general C also takes up misfit that is not damping (chains, table),
    # and requiring the family to fit as well refused every lab damper; the standard
    # errors carry the refit's own dispersion, and a damper must stand beyond the bias
    # the family's misfit can cause (_beyond_misfit; docs/method/diagnosis.md, "Dampers")
    cov = quasi_se(pd, res.z)[1] if solved else None
    return {"problem": pd, "z": res.z, "cov": cov, "chi2": float(2 * res.f),
            "chi2_general": float(state["chi"]), "excess": float(excess), "limit": limit,
            "fits": fits}


def _dense_of(A):
    return A.toarray() if hasattr(A, "toarray") else np.asarray(A)
