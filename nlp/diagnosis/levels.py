"""Level dependence (nonlinearity): the same structure tested at two excitation levels.

Each level gets its own equivalent linear fit; a story whose stiffness differs between the
levels by more than its standard errors allow is a level-dependent (nonlinear) story. The
story is placed by a shared fit of both levels that frees one story at a time.
"""

from dataclasses import replace
import math
import os

import numpy as np
from scipy.linalg import null_space

from nlp.case.assemble import assemble
from nlp.diagnosis.fitting import (best_fit, continued, diagnosis_problem, fit_target, fit_windows,
                                   noise_sigma, normalised, quasi_se, scatter_best)
from nlp.diagnosis.harmonics import harmonic_location, story_matrix
from nlp.diagnosis.level_kind import with_kind
from nlp.diagnosis.materiality import joint_gate
from nlp.diagnosis.others import assemble_other
from nlp.frf.reference import modal_parameters
from nlp.solve.search import SearchConfig

LEVEL_STARTS = 6   # scatter-search starts of each level's equivalent linear fit


def level_fit(cfg, path, z_start=None, case=None):
    """Baseline fit to one test level: story stiffnesses with standard errors, modes.

    Several starts (a short scatter search, plus z_start: another level's
    optimum), so that the equivalent model of a level is not a local minimum
    or stuck on a bound. case: the level's case, when already assembled.
    """
    c = case if case is not None else assemble(cfg, data_file=path)
    sig = noise_sigma(c, c.selected)
    tg = fit_target(c, c.selected, sig)
    pr = diagnosis_problem(c, tg)
    res, _ = scatter_best(pr, SearchConfig(starts=LEVEL_STARTS, seed=cfg.search.seed))
    if z_start is not None:
        alt = pr.solve(z_start)
        if alt.f < res.f:
            res = alt
    theta = pr.theta(res.z)
    se = quasi_se(pr, res.z)[0]
    sa, _, _ = pr.params.slices()
    nom = c.model.alpha_nominal
    lo, hi = pr.bounds
    on_bound = [bool(np.isclose(res.z[j], lo[j]) or np.isclose(res.z[j], hi[j]))
                for j in (_z_column(pr, i) for i in range(sa.start, sa.stop)) if j is not None]
    M, K, C = pr.matrices(res.z)
    fn, zeta, _ = modal_parameters(M, C, K)
    return {"case": c, "problem": pr, "z": res.z, "sigma": sig, "k": nom * (1 + theta[sa]),
            "k_se": nom * se[sa], "f": fn, "zeta": zeta, "path": path, "on_bound": on_bound}


def _z_column(pr, i):
    """The decision variable that moves theta_i (None when theta_i is fixed)."""
    row = pr.params.T[i]
    return int(np.argmax(np.abs(row))) if np.any(row != 0) else None


def level_location(ref, lv):
    """Story whose stiffness change best explains the other level's data.

    Score test at the reference level's model on the other level's data: each
    story stiffness column of the Jacobian, with the damping and mass columns
    projected out (damping also moves with the level), scored by the chi-square
    drop it would give alone. Unlike a z-score of two separate fits, it does not
    favour the story with the smallest standard error.
    """
    pr = lv["problem"]
    r, J = pr.residuals(ref["z"])
    sa, _, _ = pr.params.slices()
    cols = [_z_column(pr, i) for i in range(sa.start, sa.stop)]
    other = [j for j in range(J.shape[1]) if j not in cols]
    Q = np.linalg.qr(J[:, other])[0] if other else np.zeros((J.shape[0], 0))
    rp = r - Q @ (Q.T @ r)
    scores = []
    for j in cols:
        if j is None:
            scores.append(0.0)
            continue
        jp = J[:, j] - Q @ (Q.T @ J[:, j])
        nn = float(jp @ jp)
        scores.append(float(jp @ rp) ** 2 / nn if nn > 0 else 0.0)
    return int(np.argmax(scores)), scores


def shared_stiffness(ref, lv):
    """Do the two levels need masses and stiffnesses of their own? Likelihood ratio.

    A level's data fitted again with its masses and stiffnesses held at a common set
    (damping free: it may depend on the level) rise in chi-square over the level's own
    fit; each rise is scaled by that fit's remaining misfit. The likelihood ratio of one
    set for both levels is the least sum of the two rises over the common set, and each
    common set tried bounds it from above: the reference level's optimum (the other
    level's rise alone), the other level's (the reference's rise alone) and their
    information-weighted mean (:func:`_weighted_theta`); rises count from the lowest
    chi-square known for each level's data. The least bound is set against BIC's price of
    the held parameters (their number times ln N).

    The other level's rise alone, the test until 94de9ab, also carries the reference
    level's own error: on a linear (null) chirp case at two levels it rose to about twice
    the price. Two separate fits compared by their standard errors cannot replace the
    refits where one level determines a story poorly (a contact whose story stiffness
    changed by a quarter came out at 0.0 standard errors, its error at the high level
    far above the stiffness; see docs/method/diagnosis.md).
    """
    res, pr, params = _shared_fit(ref, lv)
    # far from the level's own optimum the damping-only fit can stop at the iteration
    # limit on its way down; continue from where it stopped (a 6 % story change of a
    # null FRF file: chi-square 86,165 unconverged after 3000 iterations)
    res = continued(pr, res)
    pr_l = lv["problem"]
    k = pr_l.params.n_z - params.n_z
    own = {"lv": _own_chi2(lv), "ref": _own_chi2(ref)}
    # chi-squares of each level's data at each common set (own optimum: exact)
    chi = {"reference": {"lv": (float(2 * res.f), bool(res.success)), "ref": (own["ref"], True)},
           "other level": {"lv": (own["lv"], True), "ref": _held_chi2(lv, ref)}}
    phi = {"lv": _phi(lv), "ref": _phi(ref)}
    limit = float(k * math.log(max(pr_l.n_used, 2)))
    th, base = _weighted_theta(ref, lv), None
    for step in range(JOINT_STEPS + 1):
        if th is None:
            break
        (a, ok_a, ga, Ha), (b, ok_b, gb, Hb) = _profiled(ref, lv, th), _profiled(lv, ref, th)
        key = "weighted" if step == 0 else f"joint step {step}"
        chi[key] = {"lv": (a, ok_a), "ref": (b, ok_b)}
        bounds = _bounds(chi, own, phi)
        least = min(v for v, _ in bounds.values())
        # the weighted set linearises at the two optima; Gauss-Newton steps on the summed
        # chi-square (damping profiled out) tighten the bound where it decides (a null case
        # has come out just above the price at the weighted set; see
        # docs/method/diagnosis.md). Far above the price the steps cannot change the
        # decision and would cost minutes
        if step == JOINT_STEPS or not limit < least < JOINT_BAND * limit:
            break
        if base is None or bounds[key][0] < bounds[base[0]][0]:
            base = (key, th, ga / phi["lv"] + gb / phi["ref"], Ha / phi["lv"] + Hb / phi["ref"])
            th = _joint_step(lv, th, base[2], base[3])
        else:   # the step overshot: half of it from the best set so far
            th = base[1] + 0.5 * (th - base[1])
    bounds = _bounds(chi, own, phi)
    at = min(bounds, key=lambda key: bounds[key][0])
    return {"chi2_shared": float(2 * res.f), "chi2_own": own["lv"],
            "held_parameters": int(k), "rise": bounds["reference"][0],
            "bounds": {key: v for key, (v, _) in bounds.items()}, "common_set": at,
            "excess": bounds[at][0], "limit": limit,
            "converged": bounds[at][1], "phi": phi["lv"],
            "theta": [float(v) for v in pr.theta(res.z)]}


JOINT_STEPS = 3     # Gauss-Newton steps towards the common set of two levels ...
JOINT_BAND = 3.0    # ... taken while the least bound is between the price and 3x it


def _bounds(chi, own, phi):
    """{common set: (summed scaled rise, converged)}. A held refit below a level's own fit
    shows that fit was a local minimum (the reference data have fitted lower at the other
    level's set than at their own optimum), so rises count from the least chi-square known."""
    best = {L: min([own[L]] + [c[L][0] for c in chi.values()]) for L in own}
    return {key: (sum((c[L][0] - best[L]) / phi[L] for L in c), all(ok for _, ok in c.values()))
            for key, c in chi.items()}


def _profiled(source, data, theta):
    """(chi-square, converged, gradient, Gauss-Newton Hessian) of ``data``'s level refitted
    with masses and stiffnesses held at theta (else source's optimum): derivatives over the
    held decision variables, the free damping projected out (variable projection)."""
    res, pr_h, _ = _shared_fit(source, data, theta_held=theta)
    res = continued(pr_h, res)
    pr = data["problem"]
    r, J = pr.residuals(pr.params.z_from_theta(pr_h.theta(res.z)))
    jh, jd = _held_columns(pr)
    A = J[:, jh]
    if jd:
        Jd = J[:, jd]
        A = A - Jd @ np.linalg.lstsq(Jd, A, rcond=None)[0]
    return float(2 * res.f), bool(res.success), 2 * A.T @ r, 2 * A.T @ A


def _held_columns(pr):
    """Decision-variable columns of the free masses and stiffnesses, and of the rest."""
    sa, sb, _ = pr.params.slices()
    jh = sorted({_z_column(pr, i) for i in range(sa.start, sb.stop)} - {None})
    return jh, [j for j in range(pr.params.n_z) if j not in jh]


def _joint_step(fit, theta, g, H):
    """theta moved by one Gauss-Newton step (g, H over the held decision variables of
    ``fit``'s problem), kept on the total-mass constraint."""
    pr = fit["problem"]
    jh, _ = _held_columns(pr)
    G = pr.constraint_jacobian()
    N = np.eye(len(jh))
    if G.size:
        N = null_space(G[:, jh])
    step = N @ np.linalg.lstsq(N.T @ H @ N, -(N.T @ g), rcond=None)[0]
    z = pr.params.z_from_theta(theta)
    z[jh] += step
    lo, hi = pr.bounds
    z[jh] = np.clip(z[jh], lo[jh], hi[jh])
    out = np.array(theta, float)
    sa, sb, _ = pr.params.slices()
    out[sa.start:sb.stop] = pr.theta(z)[sa.start:sb.stop]
    return out


def _own_chi2(fit):
    return 2 * float(fit["problem"].objective(fit["z"]))


def _phi(fit):
    """Remaining misfit of a level's own fit (reduced chi-square, at least 1)."""
    pr = fit["problem"]
    return max(_own_chi2(fit) / max(pr.n_used - pr.params.n_z, 1), 1.0)


def _held_chi2(source, data, theta_held=None):
    """(chi-square, converged) of ``data``'s level refitted with masses and stiffnesses
    held at ``source``'s optimum (or at theta_held), continued until it converges."""
    res, pr, _ = _shared_fit(source, data, theta_held=theta_held)
    res = continued(pr, res)
    return float(2 * res.f), bool(res.success)


def _held_covariance(fit):
    """Quasi-likelihood covariance of the free masses and stiffnesses (relative, Eqns
    23-24) of one level's fit, and their indices in theta."""
    pr = fit["problem"]
    _, cov = quasi_se(pr, fit["z"])
    S = pr.params.T @ cov @ pr.params.T.T
    sa, sb, _ = pr.params.slices()
    idx = [i for i in range(sa.start, sb.stop) if not pr.params.params[i].fixed]
    return S[np.ix_(idx, idx)], idx


def _weighted_theta(ref, lv):
    """The two levels' masses and stiffnesses averaged by their information:
    theta_l + S_l (S_l + S_r)^+ (theta_r - theta_l) (both fits' quasi-likelihood
    covariances), the other level's damping kept; None when they cannot be combined."""
    (Sl, idx), (Sr, idx_r) = _held_covariance(lv), _held_covariance(ref)
    if not idx or idx != idx_r:
        return None
    th_l = np.array(lv["problem"].theta(lv["z"]), float)
    th_r = np.array(ref["problem"].theta(ref["z"]), float)
    # a total-mass constraint leaves one direction without error; both optima satisfy it
    S = Sl + Sr
    d = np.linalg.pinv(S, rcond=1e-6, hermitian=True) @ (th_r[idx] - th_l[idx])
    out = th_l.copy()
    out[idx] = th_l[idx] + Sl @ d
    return out


def _shared_fit(ref, lv, release=None, theta_start=None, theta_held=None):
    """The other level's data fitted with the masses and stiffnesses held at the reference
    level's optimum (or at ``theta_held``), damping free; ``release``: the index of one
    story whose stiffness is left free as well. Returns (result, problem, parameter set)."""
    pr_l, pr_r = lv["problem"], ref["problem"]
    sa, sb, _ = pr_l.params.slices()
    theta_r = pr_r.theta(ref["z"]) if theta_held is None else np.asarray(theta_held, float)
    held = set(range(sa.start, sb.stop)) - ({sa.start + release} if release is not None else set())
    params = replace(pr_l.params, params=tuple(
        replace(p, fixed=True, initial=float(theta_r[i])) if i in held and not p.fixed else p
        for i, p in enumerate(pr_l.params.params)))
    c = lv["case"]
    pr = diagnosis_problem(c, pr_l.target, optimize=False, damping=(c.damping, params))
    # starts: the level's own damping, and the reference level's (and a given optimum)
    starts = [params.z_from_theta(pr_l.theta(lv["z"])), params.z_from_theta(theta_r)]
    if theta_start is not None:
        starts.insert(0, params.z_from_theta(theta_start))
    return best_fit(pr, starts), pr, params


def release_location(ref, lv, lr):
    """Story whose stiffness alone, left free at the other level, explains most of what the
    shared masses and stiffnesses do not: the chi-square drop of each such refit, scaled
    by the level's remaining misfit (a likelihood ratio, one parameter each). The score
    test linearises at the reference model, and has named a story far from a weak cubic
    spring's (see docs/method/diagnosis.md)."""
    sa, _, _ = lv["problem"].params.slices()
    drops = []
    for i in range(sa.stop - sa.start):
        if lv["problem"].params.params[sa.start + i].fixed:
            drops.append((0.0, True))
            continue
        res, pr, _ = _shared_fit(ref, lv, release=i, theta_start=np.asarray(lr["theta"]))
        # an unconverged drop is only a lower bound and blocks the decision: continue it
        # from where it stopped (an unconverged refit of a wrong story has stopped ahead
        # of the true story's, so the score test named the wrong one)
        res = continued(pr, res)
        drops.append((float((lr["chi2_shared"] - 2 * res.f) / lr["phi"]), bool(res.success)))
    return drops


def released_story(drops):
    """The story of the largest drop, or None when it is not certain: an unconverged refit's
    drop is only a lower bound, so every other story's refit must have converged."""
    best = int(np.argmax([d for d, _ in drops]))
    if all(ok for j, (_, ok) in enumerate(drops) if j != best):
        return best
    return None


def nonlinearity(cfg, log):
    """Compare the same model fitted to tests at different excitation levels.

    A linear structure has the same masses and stiffnesses at every level: the other
    level's data are fitted as well with the reference level's (damping free) as with
    their own, within BIC's price of the held parameters (:func:`shared_stiffness`).
    When they are not, the structure is level-dependent (nonlinear); the story is the
    one whose stiffness, freed alone, explains most of the other level's data
    (:func:`release_location`; the out-of-band harmonics decide instead when they can),
    and the equivalent stiffness and modal damping at each level are reported, with the
    z-scores of the two separate fits. None without level files.
    """
    if not cfg.data.level_files:
        return None
    ref = level_fit(cfg, cfg.data.file)
    fits, not_compared = [ref], []
    for p in cfg.data.level_files:
        c, why = assemble_other(cfg, p, log)
        if c is None:   # its data allow no fit: the other levels are still compared
            not_compared.append({"file": os.path.basename(str(p)), "reason": why})
        else:
            fits.append(level_fit(cfg, p, ref["z"], c))
    if len(fits) == 1:
        return {"found": None, "max_z": None, "not_compared": not_compared}
    out = _compare_levels(cfg, ref, fits, log)
    out["not_compared"] = not_compared
    return out


def _compare_levels(cfg, ref, fits, log):
    """:func:`nonlinearity` once the levels are fitted (fits[0] is the reference)."""
    i, zsc, lv, scores, lr = _most_different_level(ref, fits[1:])
    harm = _harmonics(cfg, fits)
    by_harmonics = bool(harm and harm["best"] is not None)
    located_by = "score test of the equivalent stiffnesses"
    if by_harmonics:
        i, located_by = harm["story_index"], "out-of-band harmonics"
    _log_levels(log, ref, lv, i, zsc, lr, harm)
    # levels that need stiffnesses of their own (an unconverged shared fit overstates it),
    # or harmonics of one story's force: a linear structure has no response where it is
    # not driven
    by_levels = lr["excess"] > lr["limit"] and lr["converged"]
    if not by_levels and not by_harmonics:
        return {"found": None, "max_z": float(np.max(np.abs(zsc))), "shared_stiffness": lr,
                "harmonics": harm}
    # every real frame's joints are slightly level-dependent: only a change beyond theirs is
    # a finding (nlp.diagnosis.materiality)
    joints, kind = joint_gate(ref, lv, lr["limit"], {"ref": _own_chi2(ref), "lv": _own_chi2(lv)},
                              {"ref": _phi(ref), "lv": _phi(lv)}, log)
    if not joints["finding"]:
        return {"found": None, "max_z": float(np.max(np.abs(zsc))), "shared_stiffness": lr,
                "harmonics": harm, "joint_band": joints}
    release = None
    if by_levels and not by_harmonics:
        # the harmonics name the story already; one refit per story costs minutes on a
        # one-segment record of several storeys (see docs/method/diagnosis.md)
        release = release_location(ref, lv, lr)
        j = released_story(release)
        if j is not None:
            i, located_by = j, "one story's stiffness freed at the other level"
        log("  one story's stiffness freed at the other level: chi-square drop (scaled) "
            + ", ".join(f"{d:.1f}" + ("" if ok else " (unconverged: at least)")
                        for d, ok in release))
        release = [{"drop": d, "converged": ok} for d, ok in release]
    before, after = _other_level_held_out(cfg, ref, lv)
    finding = _nonlinear_finding(ref, lv, i, zsc, lr, scores, release, located_by, harm,
                                 (before, after))
    # a change of mass or damping is not the family's stiffness (nlp.diagnosis.level_kind)
    finding = with_kind(ref, lv, finding, (_phi(ref), _phi(lv)), log, kind)
    return {"found": finding, "max_z": float(zsc[i]), "held_out": (before, after),
            "harmonics": harm, "shared_stiffness": lr, "joint_band": joints}


def _most_different_level(ref, others):
    """The other level whose data the reference level's stiffnesses fit worst (shared-fit
    excess over its BIC limit): (story by score test, z-scores, level, scores, shared fit)."""
    best = None
    for lv in others:
        zsc = (lv["k"] - ref["k"]) / np.sqrt(lv["k_se"] ** 2 + ref["k_se"] ** 2)
        i, scores = level_location(ref, lv)
        lr = shared_stiffness(ref, lv)
        if best is None or lr["excess"] - lr["limit"] > best[4]["excess"] - best[4]["limit"]:
            best = (i, zsc, lv, scores, lr)
    return best


def _log_levels(log, ref, lv, i, zsc, lr, harm):
    log(f"levels: story {i + 1} stiffness {ref['k'][i]:.1f} -> {lv['k'][i]:.1f} N/m "
        f"({float(zsc[i]):+.1f} standard errors; largest change {np.max(np.abs(zsc)):.1f}); the "
        f"other level's data with this level's masses and stiffnesses: chi-square "
        f"+{lr['rise']:.1f} (scaled); one set for both levels: +{lr['excess']:.1f} (at the "
        f"{lr['common_set']} set; BIC limit {lr['limit']:.1f})")
    if harm:
        log(f"  out-of-band response: {harm['z_excess']:.1f} noise SDs above the noise over "
            f"{harm['bins']} bins; one force per story explains "
            + ", ".join(f"{100 * s:.0f} %" for s in harm["share"])
            + (f": story {i + 1}" if harm["best"] is not None else ": not decided"))


def _other_level_held_out(cfg, ref, lv):
    """Held-out check on the other level: mean z^2 on its shoulders (windows 3x wider,
    not fitted) of the reference level's model and of its own equivalent model."""
    c = lv["case"]
    held = np.setdiff1d(fit_windows(cfg, c, 3), c.selected)
    sig = noise_sigma(c, held)
    before = float(np.mean(normalised(ref["problem"], ref["z"], c, held, sig) ** 2))
    after = float(np.mean(normalised(lv["problem"], lv["z"], c, held, sig) ** 2))
    return before, after


def _nonlinear_finding(ref, lv, i, zsc, lr, scores, release, located_by, harm, held_out):
    """The nonlinearity finding at story i + 1: each level's equivalent stiffness and
    modal damping, and the evidence that places it."""
    zs = float(zsc[i])
    rel = float(lv["k"][i] / ref["k"][i] - 1)
    shift = [float(100 * (b / a - 1)) for a, b in zip(ref["f"], lv["f"])]
    before, after = held_out
    return {
        "physics": "nonlinearity", "location": {"between": [i, i + 1]},
        "parameters": {f"k{i + 1}_level1": float(ref["k"][i]), f"k{i + 1}_level2": float(lv["k"][i]),
                       "relative_change": rel,
                       "damping_ratios_level1": ref["zeta"].tolist(),
                       "damping_ratios_level2": lv["zeta"].tolist()},
        "uncertainty": {f"k{i + 1}_level1": float(ref["k_se"][i]),
                        f"k{i + 1}_level2": float(lv["k_se"][i])},
        "evidence": {"z_score": zs, "z_scores": [float(x) for x in zsc], "shared_stiffness": lr,
                     "location_scores": scores, "release_drops": release,
                     "located_by": located_by, "harmonics": harm,
                     "stiffness_on_bound": ref["on_bound"] + lv["on_bound"],
                     "frequency_shift_percent": shift,
                     "held_out_chi2_other_level": {"level1_model": before, "level2_model": after}},
        "statement": _nonlinear_statement(i, rel, zs, shift, harm),
    }


def _nonlinear_statement(i, rel, zs, shift, harm):
    where = f"story {i + 1} (between {'the ground' if i == 0 else f'floor {i}'} and floor {i + 1})"
    shifts = ", ".join(f"{x:+.2f} %" for x in shift)
    tail = "A level-dependent equivalent linear model is given for each level."
    if harm and harm["best"] is not None:
        # one equivalent stiffness per level can move the wrong way on a strongly nonlinear
        # chirp record (a stiffening spring has come out softer by several standard errors;
        # see docs/method/diagnosis.md), so the harmonics lead and the change is only reported
        share = min(100 * harm["share"][harm["best"]], 100.0)
        return (f"The structure is not linear: modal frequencies shift {shifts} between "
                f"excitation levels, and the response above the excitation band (harmonics) is "
                f"that of one force across {where} ({share:.0f} % of its power above the "
                f"noise). The equivalent stiffness of that story changes by {100 * rel:+.1f} % "
                f"({zs:+.1f} standard errors). {tail}")
    return (f"The structure is not linear: the equivalent stiffness of {where} changes by "
            f"{100 * rel:+.1f} % between excitation levels ({zs:+.1f} standard errors; modal "
            f"frequencies shift {shifts}). {tail}")


def _harmonics(cfg, fits):
    """Out-of-band harmonics of the level tests (:mod:`nlp.diagnosis.harmonics`), located
    on the story patterns of the reference level's model; None without time records."""
    ref = fits[0]
    if ref["case"].records is None:
        return None
    M, K, C = ref["problem"].matrices(ref["z"])
    groups, B = story_matrix(ref["case"].model, M.shape[0])
    if B is None:
        return None
    tests = [{"records": f["case"].records, "nperseg": cfg.data.nperseg, "window": cfg.data.window,
              "H_model": (lambda w, f=f: f["problem"].channel_frfs(f["z"], w))}
             for f in fits if f["case"].records is not None]
    c = ref["case"]
    f_top = max(float(cfg.frequencies.fmax or 0.0), float(c.f[c.selected].max()))
    out = harmonic_location(tests, M, C, K, B, c.channels, f_top)
    out["groups"] = groups
    out["story_index"] = groups[out["best"]] if out["best"] is not None else None
    return out
