"""Missing physics: locate the mismatch, name what the model left out, model it.

``diagnose(cfg, out)`` runs, in order (after the set-up screening of nlp/screen.py,
which stops with the verdict setup_error when the data contradict the case):

1. the baseline update (the case's own model), with every residual divided by
   its noise level, so the objective is a chi-square;
2. a noise model per channel and frequency, for the FRF's route (one-segment
   transient, Welch averages, FRF file): :mod:`nlp.noise`;
3. a residual map (channel x band): mean squared normalised residual in each
   fitted half-power window and in the held-out shoulders around it (points
   1-3 windows from a peak, never fitted);
4. a cheap ranking of every candidate family x location by a score test:
   the baseline residual projected off the baseline Jacobian, onto the
   candidate's Jacobian columns at its null value (expected chi-square drop);
   candidates whose columns lie almost inside the baseline span are reported
   as absorbed by the baseline parameters, not guessed at;
5. a refit of the best few with the same NLP; a candidate is accepted when
   BIC drops by at least 10, the held-out chi-square improves and its
   parameters are inside their physical bounds;
6. the verdict: adequate, missing_physics, or ambiguous (accepted candidates
   that fit alike, or a mismatch none explains), with the measurement that
   would separate them.
"""

from dataclasses import replace
import math
import os

import numpy as np

from .case import _half_power, assemble
from .noise import sigma_ln
from .physics import (AddedMass, BaseFlexibility, HystereticDamping, LocalDamper,
                      NonadjacentCoupling, SecondaryOscillator, SensorDelay, SensorGain,
                      extend_parameters, references)
from .problem import SolverConfig, Target, UpdatingProblem
from .search import SearchConfig, scatter_search

__all__ = ["diagnose", "noise_sigma", "candidates", "SUGGESTIONS"]

BIC_ACCEPT = 10.0      # "very strong" evidence (Kass & Raftery)
BIC_TIE = 6.0          # accepted candidates closer than this cannot be told apart
HELD_OUT_GAIN = 0.8    # accepted physics must cut the held-out chi-square by 20 % or more
ABSORBED = 0.05        # fraction of a candidate's effect left after projection

SUGGESTIONS = {
    "added_mass": "weigh the floor, or repeat the test with a known added mass",
    "base_flexibility": "a sensor on the base (table) to measure the base motion directly",
    "secondary_oscillator": "a sensor on the suspected appendage, or a shaker at another floor",
    "local_damper": "a second excitation level or a wider frequency band around the higher modes",
    "hysteretic_damping": "FRFs over a wider frequency band (viscous and hysteretic loss differ "
                          "in how damping grows with frequency)",
    "nonadjacent_coupling": "a second shaker position (force at another floor)",
    "sensor_gain": "a calibration check of that sensor, or a second sensor on the same floor",
    "sensor_delay": "the phase of the FRFs (complex residual) or a check of the acquisition timing",
    "nonlinearity": "the same test at a second excitation level",
}
LEVEL_Z = 5.0          # story-stiffness change between levels, in standard errors


# ---------------------------------------------------------------------- noise
def noise_sigma(case, idx):
    """Standard deviation of ln|H| at points idx of every channel: (n_ch, len(idx)),
    per frequency, from the noise model of the case's FRF route (nlp/noise.py)."""
    return sigma_ln(case, idx)


# ------------------------------------------------------------------ problems
def _target(case, idx, sigma):
    tg = case.target
    return Target(omega=2 * np.pi * case.f[idx], H=case.H[:, idx], weight=1.0 / sigma,
                  channels=tg.channels, excitation=tg.excitation, force_dof=tg.force_dof)


def _problem(case, target, enrichments=(), values=None, compile=True):
    cfg = case.config
    refs = _refs(case)
    params = extend_parameters(case.params, enrichments, refs, values)
    solver = SolverConfig(cfg.solver.name, dict(cfg.solver.options), compile)
    residual = "complex" if cfg.objective.residual == "complex" else "log_magnitude"
    return UpdatingProblem(case.model, case.damping, params, target, residual=residual,
                           solver=solver, total_mass=cfg.parameters.total_mass,
                           enrichments=enrichments, refs=refs)


def _normalised(problem, z, case, idx, sigma):
    """Residuals over noise: ln|Ha/Hx|, or |ln(Ha/Hx)| / sqrt(2) when phase is fitted."""
    Ha = problem.channel_frfs(z, 2 * np.pi * case.f[idx])
    d = np.log(Ha / case.H[:, idx])
    if case.config.objective.residual == "complex":
        return np.abs(d) / np.sqrt(2) / sigma
    return d.real / sigma


def _fit(problem, z0_list):
    best = None
    for z0 in z0_list:
        r = problem.solve(z0)
        if best is None or r.f < best.f:
            best = r
    return best


# ---------------------------------------------------------------- candidates
def candidates(case):
    """Every family x location that the data could reveal, but the secondary
    oscillator (scanned separately; sensor delay needs the phase)."""
    n = case.model.n
    out = [AddedMass(i) for i in range(1, n + 1)]
    out.append(BaseFlexibility())
    out += [LocalDamper(i, i - 1) for i in range(1, n + 1)]
    out += [HystereticDamping()] + [HystereticDamping(s) for s in range(1, n + 1)]
    out += [NonadjacentCoupling(i, j) for i in range(1, n + 1) for j in range(i + 2, n + 1)]
    out += [SensorGain(ch.name) for ch in case.channels]
    if case.config.objective.residual == "complex":
        out += [SensorDelay(ch.name) for ch in case.channels]
    return out


def _to_refit(scored, top):
    """Every competitive candidate (score within a factor 3 of the best, at most
    2 x top) and the two best locations of every family: the score test is a
    first-order look, and a large effect can rank its true location second."""
    if not scored:
        return []
    best = scored[0][0]
    chosen = [(s, e) for s, e in scored if s >= best / 3][:2 * top]
    count = {}
    for s, e in chosen:
        count[e.family] = count.get(e.family, 0) + 1
    for s, e in scored:
        if s > 0 and count.get(e.family, 0) < 2 and (s, e) not in chosen:
            chosen.append((s, e))
            count[e.family] = count.get(e.family, 0) + 1
    return chosen


def _refs(case):
    return references(case.model, getattr(case.damping, "C0", np.eye(case.model.n)))


def _at(pr, z_cur, values):
    """Decision vector: the current model's, then the new enrichment's parameters."""
    k = len(values)
    theta = pr.theta(np.concatenate([z_cur, np.zeros(pr.params.n_z - z_cur.size)]))
    theta[-k:] = values
    return np.concatenate([z_cur, pr.params.z_from_theta(theta)[z_cur.size:]])


def _score_at(pr, z, k):
    """Expected chi-square drop of freeing the last k variables, and the fraction of
    their effect left after projecting out the baseline Jacobian."""
    r, J = pr.residuals(z)
    Jb, Je = J[:, :-k], J[:, -k:]
    Q, _ = np.linalg.qr(Jb)
    Jp = Je - Q @ (Q.T @ Je)
    rp = r - Q @ (Q.T @ r)
    raw = np.linalg.norm(Je)
    kept = float(np.linalg.norm(Jp) / raw) if raw > 0 else 0.0
    if kept < 1e-9:
        return 0.0, kept
    g = Jp.T @ rp
    return float(g @ np.linalg.pinv(Jp.T @ Jp) @ g), kept


def _score(case, target, current, z_cur, enrichment):
    """Score test of one candidate at its null value, on top of the current model."""
    null = enrichment.spec(_refs(case))["null"]
    pr = _problem(case, target, current + [enrichment], compile=False)
    return _score_at(pr, _at(pr, z_cur, null), len(enrichment.names))


def _scan_secondary(case, target, current, z_cur, n_grid=48):
    """Best appendage frequency per floor: the score of a tiny oscillator scanned over
    the band (its frequency is a nuisance parameter, undefined under the null)."""
    f_sel = case.f[case.selected]
    grid = np.geomspace(0.8 * f_sel.min(), 1.1 * f_sel.max(), n_grid)
    out = []
    for floor in range(1, case.model.n + 1):
        if any(e.family == "secondary_oscillator" and e.floor == floor for e in current):
            continue
        e = SecondaryOscillator(floor, float(grid[0]))
        pr = _problem(case, target, current + [e], compile=False)
        scores = [_score_at(pr, _at(pr, z_cur, [1e-4, f0, 0.02]), 3) for f0 in grid]
        best = int(np.argmax([sc for sc, _ in scores]))
        out.append((SecondaryOscillator(floor, float(grid[best])), scores[best]))
    return out


# --------------------------------------------------------------------- main
def _bands(f_idx):
    """Contiguous groups of fitted points: one band per half-power window."""
    groups, start = [], 0
    for k in range(1, len(f_idx) + 1):
        if k == len(f_idx) or f_idx[k] - f_idx[k - 1] > 1:
            groups.append(np.arange(start, k))
            start = k
    return groups


def _residual_map(case, problem, z, fit, held, sig_fit, sig_held):
    rf = _normalised(problem, z, case, fit, sig_fit)
    rh = _normalised(problem, z, case, held, sig_held)
    cells = []
    for b, g in enumerate(_bands(fit)):
        lo, hi = case.f[fit[g[0]]], case.f[fit[g[-1]]]
        width = hi - lo
        near = (case.f[held] >= lo - 3 * width) & (case.f[held] <= hi + 3 * width)
        for c, ch in enumerate(case.channels):
            cells.append({"channel": ch.name, "band_hz": [float(lo), float(hi)],
                          "fitted": float(np.mean(rf[c, g] ** 2)),
                          "held_out": float(np.mean(rh[c, near] ** 2)) if near.any() else None})
    return cells, rf, rh


def _refit(case, target, current, z_cur, e, score, ref_chi, ref_held, n_fit, held, sig_held):
    """Fit the current model plus candidate e; evidence against the current model."""
    from .identify import standard_errors
    refs = _refs(case)
    pr = _problem(case, target, current + [e])
    k = len(e.names)
    sp = e.spec(refs)
    # start the added parameters inside their box, not on a zero bound
    start = [max(v, lo_ + 0.5 * sc) if v <= lo_ else v
             for v, lo_, sc in zip(sp["initial"], sp["lower"], sp["scale"])]
    # the added parameters start at the family's guess and at two seeded points of their box
    rng = np.random.default_rng(len(current) * 7919 + sum(map(ord, repr(e))))
    box = [[lo_ + (hi_ - lo_) * rng.uniform(0.05, 0.6) for lo_, hi_ in zip(sp["lower"], sp["upper"])]
           for _ in range(2)]
    extra = e.starts(refs) if hasattr(e, "starts") else []
    res = _fit(pr, [_at(pr, z_cur, v) for v in [start] + extra + box])
    theta_e = pr.theta(res.z)[-k:]
    at_bound = any(abs(t - b) <= 1e-5 * max(abs(sc), 1e-12)
                   for t, lo_, hi_, sc in zip(theta_e, sp["lower"], sp["upper"], sp["scale"])
                   for b in (lo_, hi_) if b != 0.0)
    chi = 2 * res.f
    rh = _normalised(pr, res.z, case, held, sig_held)
    r, J = pr.residuals(res.z)
    cov, _, _ = standard_errors(J, r, pr.n_used)
    se = np.sqrt(np.clip(np.diag(pr.params.T @ cov @ pr.params.T.T), 0, None))[-k:]
    entry = {"physics": e.family, "location": e.location, "enrichment": e,
             "parameters": dict(zip(e.names, map(float, theta_e))),
             "uncertainty": dict(zip(e.names, map(float, se))),
             "score": score, "chi2": chi, "delta_bic": chi - ref_chi + k * math.log(n_fit),
             "held_out": float(np.mean(rh ** 2)), "at_bound": at_bound, "z": res.z, "problem": pr}
    # strong evidence on the fitted points with a held-out gain, or a held-out error
    # halved by the added physics while the fit does not get worse
    entry["accepted"] = not at_bound and (
        (entry["delta_bic"] <= -BIC_ACCEPT and entry["held_out"] <= HELD_OUT_GAIN * ref_held)
        or (entry["delta_bic"] <= 0 and entry["held_out"] <= 0.5 * ref_held))
    return entry


def _level_fit(cfg, path):
    """Baseline fit to one test level: story stiffnesses with standard errors, modes."""
    from .frf import modal_parameters
    from .identify import standard_errors
    c = assemble(cfg, data_file=path)
    sig = noise_sigma(c, c.selected)
    tg = _target(c, c.selected, sig)
    pr = _problem(c, tg)
    res = _fit(pr, [pr.z0])
    r, J = pr.residuals(res.z)
    cov, _, _ = standard_errors(J, r, pr.n_used)
    theta = pr.theta(res.z)
    se = np.sqrt(np.clip(np.diag(pr.params.T @ cov @ pr.params.T.T), 0, None))
    sa, _, _ = pr.params.slices()
    nom = c.model.alpha_nominal
    M, K, C = pr.matrices(res.z)
    fn, zeta, _ = modal_parameters(M, C, K)
    return {"case": c, "problem": pr, "z": res.z, "sigma": sig, "k": nom * (1 + theta[sa]),
            "k_se": nom * se[sa], "f": fn, "zeta": zeta, "path": path}


def _nonlinearity(cfg, log):
    """Compare the same model fitted to tests at different excitation levels.

    A linear structure gives the same story stiffnesses at every level, within
    their standard errors; a story whose equivalent stiffness moves by more than
    LEVEL_Z standard errors is reported as level-dependent (nonlinear), with the
    equivalent stiffness and the modal damping at each level.
    """
    if not cfg.data.level_files:
        return None
    fits = [_level_fit(cfg, p) for p in (cfg.data.file,) + tuple(cfg.data.level_files)]
    ref = fits[0]
    best = None
    for lv in fits[1:]:
        zsc = (lv["k"] - ref["k"]) / np.sqrt(lv["k_se"] ** 2 + ref["k_se"] ** 2)
        i = int(np.argmax(np.abs(zsc)))
        if best is None or abs(zsc[i]) > abs(best[1]):
            best = (i, float(zsc[i]), lv)
    i, zs, lv = best
    log(f"levels: story {i + 1} stiffness {ref['k'][i]:.1f} -> {lv['k'][i]:.1f} N/m "
        f"({zs:+.1f} standard errors)")
    if abs(zs) < LEVEL_Z:
        return {"found": None, "max_z": zs}
    # held-out check on the other level: its own equivalent model against the reference one
    c = lv["case"]
    cfg3 = replace(cfg, frequencies=replace(cfg.frequencies, k=3 * cfg.frequencies.k))
    wide = np.asarray(_half_power(cfg3, c.f, c.H, c.channels, c.target.excitation, c.coherence,
                                  c.noise.sigma_ln), int)
    held = np.setdiff1d(wide[c.f[wide] > 0], c.selected)
    sig = noise_sigma(c, held)
    before = float(np.mean(_normalised(ref["problem"], ref["z"], c, held, sig) ** 2))
    after = float(np.mean(_normalised(lv["problem"], lv["z"], c, held, sig) ** 2))
    rel = float(lv["k"][i] / ref["k"][i] - 1)
    shift = [float(100 * (b / a - 1)) for a, b in zip(ref["f"], lv["f"])]
    finding = {
        "physics": "nonlinearity", "location": {"between": [i, i + 1]},
        "parameters": {f"k{i + 1}_level1": float(ref["k"][i]), f"k{i + 1}_level2": float(lv["k"][i]),
                       "relative_change": rel,
                       "damping_ratios_level1": ref["zeta"].tolist(),
                       "damping_ratios_level2": lv["zeta"].tolist()},
        "uncertainty": {f"k{i + 1}_level1": float(ref["k_se"][i]),
                        f"k{i + 1}_level2": float(lv["k_se"][i])},
        "evidence": {"z_score": zs, "frequency_shift_percent": shift,
                     "held_out_chi2_other_level": {"level1_model": before, "level2_model": after}},
        "statement": (f"The structure is not linear: the equivalent stiffness of story {i + 1} "
                      f"(between {'the ground' if i == 0 else f'floor {i}'} and floor {i + 1}) "
                      f"changes by {100 * rel:+.1f} % between excitation levels "
                      f"({zs:+.1f} standard errors; modal frequencies shift "
                      f"{', '.join(f'{x:+.2f} %' for x in shift)}). A level-dependent "
                      "equivalent linear model is given for each level."),
    }
    return {"found": finding, "max_z": zs, "held_out": (before, after)}


def _prune(case, target, found, state, n_fit, held, sig_held, log):
    """Backward elimination: drop a finding that the others make unnecessary (removing
    it costs less than BIC_ACCEPT), then refit what is left and report its values."""
    from .identify import standard_errors
    while len(found) > 1:
        best_drop = None
        for r in found:
            keep = [x for x in found if x is not r]
            pr = _problem(case, target, [x["enrichment"] for x in keep])
            z = np.concatenate([state["z"][:pr.params.n_z - sum(len(x["parameters"]) for x in keep)]]
                               + [_params_z(pr, x, state) for x in keep])
            res = _fit(pr, [z])
            cost = 2 * res.f - state["chi"] - len(r["parameters"]) * math.log(n_fit)
            if cost < BIC_ACCEPT and (best_drop is None or cost < best_drop[0]):
                best_drop = (cost, r, keep, pr, res)
        if best_drop is None:
            break
        cost, r, keep, pr, res = best_drop
        log(f"  dropped {r['physics']} {r['location']}: the other findings explain it "
            f"(BIC cost {cost:.1f})")
        rh = _normalised(pr, res.z, case, held, sig_held)
        state = {"current": [x["enrichment"] for x in keep], "z": res.z, "chi": 2 * res.f,
                 "held": float(np.mean(rh ** 2)), "problem": pr}
        found = keep
    # values and errors of the final set, from its own fit
    pr, z = state["problem"], state["z"]
    r, J = pr.residuals(z)
    cov, _, _ = standard_errors(J, r, pr.n_used)
    theta = pr.theta(z)
    se = np.sqrt(np.clip(np.diag(pr.params.T @ cov @ pr.params.T.T), 0, None))
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


def _same(e, current):
    return any(c.family == e.family and c.location == e.location for c in current)


def _adequate(chi, nu, held):
    return chi / nu < 1.5 + 3 * math.sqrt(2 / nu) and held < 2.0


def _windows(cfg, case, mult):
    """Points within mult x k half-power bandwidths of the peaks."""
    if mult == 1:
        return case.selected
    c = replace(cfg, frequencies=replace(cfg.frequencies, k=mult * cfg.frequencies.k))
    idx = np.asarray(_half_power(c, case.f, case.H, case.channels, case.target.excitation,
                                 case.coherence, case.noise.sigma_ln), int)
    return idx[case.f[idx] > 0]


def diagnose(cfg, out, log=print, top=4, max_findings=3, widen=1):
    """Diagnose a case; writes out/diagnosis.json and figures; returns the dict.

    Forward selection: each round adds the best accepted candidate to the model
    and looks again, until the model explains the data, nothing more is
    accepted, candidates tie (ambiguous), or max_findings are found. When the
    fitted windows are explained but the held-out shoulders are not, and no
    family is accepted, the windows are widened 3x once and the search repeated
    (the effect lives off the resonances).
    """
    case = assemble(cfg)
    screening = _screen(case, out, log) if widen == 1 else None
    if screening is not None and screening["verdict"] == "setup_error":
        return screening
    fit = _windows(cfg, case, widen)
    held = np.setdiff1d(_windows(cfg, case, 3 * widen), fit)
    sig_fit, sig_held = noise_sigma(case, fit), noise_sigma(case, held)
    target = _target(case, fit, sig_fit)
    base = _problem(case, target)
    # a poor baseline optimum would make any added parameter look useful
    b_res = scatter_search(base, SearchConfig(starts=max(cfg.search.starts, 20),
                                              seed=cfg.search.seed), progress=None).best
    n_fit = base.n_used
    chi_b = 2 * b_res.f
    nu = max(n_fit - base.params.n_z, 1)
    cells, _, rh0 = _residual_map(case, base, b_res.z, fit, held, sig_fit, sig_held)
    held_b = float(np.mean(rh0 ** 2))
    log(f"baseline: reduced chi-square {chi_b / nu:.2f} on {n_fit} fitted points, "
        f"held-out {held_b:.2f} on {rh0.size} points")
    state = {"current": [], "z": b_res.z, "chi": chi_b, "held": held_b, "problem": base}
    found, alternatives, absorbed, ties, tried = [], [], [], [], []
    for rnd in range(max_findings):
        if _adequate(state["chi"], nu, state["held"]) and rnd > 0:
            break
        pairs = [(e, _score(case, target, state["current"], state["z"], e))
                 for e in candidates(case) if not _same(e, state["current"])]
        pairs += _scan_secondary(case, target, state["current"], state["z"])
        if rnd == 0:
            absorbed = [{"physics": e.family, "location": e.location, "fraction_left": kept}
                        for e, (_, kept) in pairs if kept < ABSORBED]
        scored = sorted(((sc, e) for e, (sc, _) in pairs), key=lambda t: -t[0])
        results = []
        for sc, e in _to_refit(scored, top):
            r = _refit(case, target, state["current"], state["z"], e, sc, state["chi"],
                       state["held"], n_fit, held, sig_held)
            results.append(r)
            log(f"  [{rnd + 1}] {e.family} {e.location}: score {sc:.1f}, dBIC {r['delta_bic']:.1f}, "
                f"held-out {r['held_out']:.2f}{' (accepted)' if r['accepted'] else ''}")
        tried += results
        accepted = sorted([r for r in results if r["accepted"]], key=lambda r: r["delta_bic"])
        if not accepted:
            break
        best = accepted[0]
        ties = [r for r in accepted[1:] if r["delta_bic"] - best["delta_bic"] < BIC_TIE]
        if ties and rnd > 0:
            # a further effect the data cannot attribute: report, do not add
            alternatives += accepted
            ties = []
            break
        found.append(best)
        alternatives += accepted[1:]
        if ties:
            break
        state = {"current": state["current"] + [best["enrichment"]], "z": best["z"],
                 "chi": best["chi2"], "held": best["held_out"], "problem": best["problem"]}
    if len(found) > 1:
        found, state = _prune(case, target, found, state, n_fit, held, sig_held, log)
    if (widen == 1 and not found and chi_b / nu < 1.5 + 3 * math.sqrt(2 / nu)
            and not _adequate(chi_b, nu, held_b)):
        log("the fitted windows are explained but the held-out shoulders are not: "
            "widening the windows 3x and looking again")
        return diagnose(cfg, out, log, top, max_findings, widen=3)
    nonlin = _nonlinearity(cfg, log)
    return _verdict(cfg, case, out, log, base, b_res, found, alternatives, ties, tried, absorbed,
                    cells, fit, held, sig_fit, sig_held, chi_b, nu, held_b, state, nonlin,
                    screening=screening and screening["report"])


def _screen(case, out, log):
    """Screen the data before fitting (nlp/screen.py). A case that contradicts its data
    gets the verdict setup_error, written to out/diagnosis.json; otherwise the screening
    is returned for the diagnosis to carry."""
    from .results import write_json
    from .screen import screen, setup_error_result
    report = screen(case)
    for w in report["warnings"]:
        log(f"screening: {w['message']}")
    if not report["setup_errors"]:
        return {"verdict": None, "report": report}
    result = setup_error_result(report)
    os.makedirs(out, exist_ok=True)
    write_json(os.path.join(out, "diagnosis.json"), result)
    log("verdict: setup_error (the data contradict the case; no physics is blamed)")
    for e in report["setup_errors"]:
        log(f"  set-up error: {e['message']}")
    return result


def _statement(r):
    loc = r["location"]
    if "floor" in loc:
        where = f"at floor {loc['floor']}"
    elif "between" in loc:
        a, b = loc["between"]
        where = f"between {'the ground' if a == 0 else f'floor {a}'} and floor {b}"
    elif "channel" in loc:
        where = f"on channel {loc['channel']}"
    else:
        where = "of the whole structure"
    pars = ", ".join(f"{k} = {v:.4g} +- {r['uncertainty'][k]:.2g}"
                     for k, v in r["parameters"].items())
    words = {"added_mass": "an unmodelled mass", "base_flexibility": "a flexible base",
             "secondary_oscillator": "a secondary oscillator (appendage)",
             "local_damper": "a concentrated damper", "hysteretic_damping": "hysteretic damping",
             "nonadjacent_coupling": "a stiffness coupling (non-shear behaviour)",
             "sensor_gain": "a sensor gain error", "sensor_delay": "a sensor time delay"}
    return f"The data show {words[r['physics']]} {where} ({pars})."


def _public(r):
    d = {k: r[k] for k in ("physics", "location", "parameters", "uncertainty")}
    d["evidence"] = {"score": r["score"], "delta_bic": r["delta_bic"], "chi2": r["chi2"],
                     "held_out_chi2": r["held_out"]}
    d["statement"] = _statement(r)
    return d


def _verdict(cfg, case, out, log, base, b_res, found, alternatives, ties, tried, absorbed, cells,
             fit, held, sig_fit, sig_held, chi_b, nu, held_b, state, nonlin=None, screening=None):
    from .diagnose_plots import plot_diagnosis
    from .results import write_json
    suggestions = []
    if found and ties:
        verdict = "ambiguous"
        for r in [found[-1]] + ties:
            if SUGGESTIONS[r["physics"]] not in suggestions:
                suggestions.append(SUGGESTIONS[r["physics"]])
    elif found or (nonlin and nonlin["found"]):
        verdict = "missing_physics"
    elif _adequate(chi_b, nu, held_b):
        verdict = "adequate"
    else:
        verdict = "ambiguous"
        suggestions = list(dict.fromkeys(SUGGESTIONS[r["physics"]] for r in tried[:2]))
    improved, z_imp = state["problem"], state["z"]
    cells_after, _, _ = _residual_map(case, improved, z_imp, fit, held, sig_fit, sig_held)
    k = improved.params.n_z - base.params.n_z
    fit_before = {"objective": b_res.f, "reduced_chi2": chi_b / nu, "held_out_chi2": held_b}
    fit_after = {"objective": state["chi"] / 2, "reduced_chi2": state["chi"] / max(nu - k, 1),
                 "held_out_chi2": state["held"]}
    if nonlin and nonlin["found"] and not found:
        before_o, after_o = nonlin["held_out"]
        fit_before["other_level_held_out_chi2"] = before_o
        fit_after = dict(fit_before, other_level_held_out_chi2=after_o)
    remaining = bool(found) and not _adequate(state["chi"], max(nu - k, 1), state["held"])
    statements = [_statement(r) for r in found]
    findings = [_public(r) for r in found]
    if nonlin and nonlin["found"]:
        findings.insert(0, nonlin["found"])
        statements.insert(0, nonlin["found"]["statement"])
    elif not cfg.data.level_files and (verdict == "ambiguous" or remaining):
        suggestions.append(SUGGESTIONS["nonlinearity"] + " (to rule out nonlinearity)")
    if remaining:
        statements.append("With this added, residuals are still above the noise: more is "
                          "missing than the candidate families describe.")
    if verdict == "ambiguous" and not found:
        statements.append("The model does not explain the data within the noise, and no "
                          "candidate family explains the mismatch.")
    chosen = {(r["physics"], repr(r["location"])) for r in found}
    absorbed = [a for a in absorbed if (a["physics"], repr(a["location"])) not in chosen]
    alts, seen = [], set(chosen)
    for r in sorted(alternatives, key=lambda r: r["delta_bic"]):
        key = (r["physics"], repr(r["location"]))
        if key not in seen:
            seen.add(key)
            alts.append(r)
    alternatives = alts
    result = {"verdict": verdict, "findings": findings,
              "alternatives": [_public(r) for r in alternatives], "absorbed": absorbed,
              "summary": statements, "remaining_mismatch": remaining,
              "fit": {"before": fit_before, "after": fit_after},
              "residual_map": {"before": cells, "after": cells_after},
              "suggested_measurements": suggestions}
    if screening is not None:
        result["screening"] = screening
    os.makedirs(out, exist_ok=True)
    plot_diagnosis(out, case, base, b_res.z, improved, z_imp, cells, cells_after,
                   " + ".join(r["physics"] for r in found) if found else None)
    write_json(os.path.join(out, "diagnosis.json"), result)
    log(f"verdict: {verdict}")
    for st in statements:
        log("  " + st)
    if alternatives:
        log("  alternatives: " + "; ".join(f"{a['physics']} {a['location']}" for a in alternatives))
    for sg in suggestions:
        log(f"  suggested measurement: {sg}")
    log(f"  fit before: reduced chi-square {fit_before['reduced_chi2']:.2f}, held-out "
        f"{fit_before['held_out_chi2']:.2f}; after: {fit_after['reduced_chi2']:.2f}, "
        f"{fit_after['held_out_chi2']:.2f}")
    return result
