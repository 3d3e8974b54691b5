"""Missing physics: locate the mismatch, name what the model left out, model it.

``diagnose(cfg, out)`` is a pipeline of stages, each a function of the previous
stages' data (:mod:`nlp.diagnosis.look`):

1. screen: the set-up screening (:mod:`.screen`), which stops with the verdict
   setup_error when the data contradict the case;
2. points and baseline: the case's own model updated on its half-power windows, with
   every residual divided by its noise level (so the objective is a chi-square), the
   noise model of the FRF's route (:mod:`nlp.frf.noise`), and the residual map
   (channel x window: fitted points, and held-out shoulders 1-3 windows from a peak);
3. levels: a structure that depends on the excitation level (:mod:`.levels`);
4. selection: rounds of candidates (:mod:`.candidates`) ranked by a score test and
   the best few refitted with the same NLP (:mod:`.refit`); a candidate is accepted
   when the scaled BIC drops by BIC_ACCEPT, the held-out chi-square improves and its
   parameters are inside their physical bounds (:mod:`.decide`), and when it holds on
   the case's other tests (:mod:`.others`);
5. widen: a second look over wider windows when the mismatch lives between them
   (:mod:`.widen`);
6. checks: effects inside the model class (:mod:`.inside`), phase, loss and the whole
   band (:mod:`.checks`);
7. verdict: adequate, setup_error (only a channel's gain or delay found), missing_physics,
   partly_explained or ambiguous, with the measurement that would
   separate the candidates (:mod:`.verdict`).
"""

from dataclasses import replace
import math

import numpy as np

from nlp.case.assemble import assemble
from nlp.case.checks import check_start_residuals
from nlp.diagnosis.asymmetry import story_asymmetry, with_asymmetry
from nlp.diagnosis.candidates import (ABSORBED, candidates, hot_appendages, same,
                                      scan_secondary, score, to_refit)
from nlp.diagnosis.checkpoint import (budget_note, budget_over, budget_spent, fingerprint,
                                      logged_step, recording, refits_step, repolish_step, step)
from nlp.diagnosis.checks import loss_check, phase_check, unexplained, whole_band
from nlp.diagnosis.decide import adequate, better_unresolved, decide
from nlp.diagnosis.discrepancy import (extra_modes_in_band, kept_discrepancy,
                                       own_modes_in_band, refute_in_discrepancy)
from nlp.diagnosis.evidence import BIC_ACCEPT, BIC_TIE, HELD_OUT_GAIN, evidence, tied
from nlp.diagnosis.fitting import (best_fit, diagnosis_problem, fit_target, fit_windows,
                                   noise_sigma, residual_map, scatter_best, signed)
from nlp.diagnosis.gains import calibration_stage, confirmed_gains
from nlp.diagnosis.inside import inside_model_class
from nlp.diagnosis.joint import alone_fits, reciprocity_of_tests
from nlp.diagnosis.levels import nonlinearity
from nlp.diagnosis.look import Baseline, Checks, Options, Points, Seed, Selection
from nlp.diagnosis.nuisance import hold_open_nuisance, why_refused
from nlp.diagnosis.others import final_records, hold_on_others, refits_of_others, setup_others
from nlp.diagnosis.reciprocity import reciprocal_pairs, refute_gains
from nlp.diagnosis.reduction import recentre_baseline, uses_reduced
from nlp.diagnosis.refit import MAX_REPOLISH, continue_refit, prune, refit_all, repolish
from nlp.diagnosis.screen import screen_stage
from nlp.diagnosis.spread import chi2_spread
from nlp.diagnosis.sweep import carried, final_sweep, sweep_stage
from nlp.diagnosis.verdict import SUGGESTIONS, verdict_stage, write_conclusion
from nlp.diagnosis.widen import (WIDEN, hot_windows, keeps_findings, leaves_shoulders, off_peak,
                                 refuted_on_wider)
from nlp.frf.noise import describe as describe_noise
from nlp.output.progress import advance, steps
from nlp.solve.executors import Setup
from nlp.solve.search import SearchConfig

__all__ = ["diagnose", "candidates", "SUGGESTIONS", "BIC_ACCEPT", "BIC_TIE",
           "HELD_OUT_GAIN"]

# A nonlinear structure whose reference level the linear model misses by more than this
# reduced chi-square (windows or shoulders) is not searched for linear candidates: any
# candidate's gain is the nonlinearity's (docs/method/diagnosis.md, decision constants).
LEVEL_MISFIT = 10.0
STAGES = ("screen", "points", "baseline", "levels", "discrepancy", "selection", "widen", "checks", "verdict")
BASELINE_STARTS = 20   # least scatter-search starts of the baseline: a poor optimum there
                       # would make any added parameter look useful


def diagnose(cfg, out, log=print, top=4, max_findings=3, widen=1, resume=False, ckpt_out=None,
             budget=None):
    """Diagnose a case; writes out/diagnosis.json and figures; returns the dict.

    Forward selection: each round adds the best accepted candidate to the model and
    looks again, until the model explains the data, nothing more is accepted,
    candidates tie (ambiguous), or max_findings are found (top: candidates refitted per
    round, doubled for close scores). widen: the first look's windows, in half-power
    bandwidths; only a first look of 1 may widen (nlp.diagnosis.widen). Each search and
    round is kept in ckpt_out's checkpoint (default: out's; nlp.diagnosis.checkpoint) until
    the diagnosis completes; resume takes the finished ones from it. budget [s]: no stage
    (the model discrepancy, a round, the widened look) starts after it is spent.
    """
    with steps("diagnose", len(STAGES)) as bar, \
            recording(ckpt_out or out, cfg, (top, max_findings, widen), resume, bar.around(log),
                      budget):
        log = bar.around(log)
        case = assemble(cfg)
        screening = None
        if widen == 1:
            screening = screen_stage(cfg, case, out, log)
            if screening["verdict"] == "setup_error":
                return screening
            screening = screening["report"]
        conclusion = first_look(cfg, case, Options(top, max_findings), widen, screening, log)
        write_conclusion(out, conclusion)
    return conclusion.result


# ------------------------------------------------------------------- looks
def first_look(cfg, case, opts, widen, screening, log):
    """Baseline, level comparison and selection over the case's windows; then either a
    widened look (when it stands) or this look's checks and verdict."""
    points = points_stage(cfg, case, widen, (), log)
    base = baseline_stage(cfg, case, points, None, log)
    if uses_reduced(case):
        case, points, base = reduced_stage(cfg, case, points, base, log)
    refit = refit_from(cfg, log)
    case, points, base = sweep_stage(case, points, base, log, refit)
    case, points, base = calibration_stage(case, points, base, log, refit)
    if case.released_gains:   # the joints' bend estimated again with the gains named
        case, points, base = sweep_stage(case, points, base, log, refit)
    advance("diagnose", "levels")
    nonlin = logged_step("levels", fingerprint(cfg.data.level_files),
                         lambda lg: nonlinearity(cfg, lg), log)
    nonlin = with_asymmetry(nonlin, story_asymmetry(cfg, case, points.base, base.res.z, log))
    level_bound = level_stage(base, nonlin, log)
    if level_bound:
        # the model discrepancy keeps linear candidates from absorbing resonances the model
        # class lacks; a level-bound structure has no linear candidate searched, and on its
        # records (harmonics, level mixing) the discrepancy's refits took most of a diagnosis
        advance("diagnose", "discrepancy")
    else:
        case, points, base = discrepancy_stage(cfg, case, points, base, widen, log)
    sel, base = selection_stage(cfg, case, points, base, level_bound, None, opts, log)
    case, sel.state = confirmed_gains(case, points, sel.state, base.nu, base.n_fit, log)
    if widen == 1 and not level_bound and not case.outside_class:
        wide = widen_stage(cfg, case, points, base, sel, nonlin, opts, log)
        if wide is not None:
            return wide
    return conclude(cfg, case, points, base, sel, nonlin, level_bound, screening, log)


def widened_look(cfg, opts, nonlin, hot, seed, log, first):
    """The look over windows WIDEN x wider, with windows at the hot frequencies [Hz]; the
    level comparison is the first look's (nonlin); seed: the first look's optima and
    findings (a look after findings), or None (a look after none); first: the first look's
    case, whose model discrepancy is kept (its windows too) and reduced basis reused."""
    discrepancy = first.discrepancy
    case = replace(assemble(cfg), discrepancy=tuple(discrepancy), basis_centre=first.basis_centre,
                   outside_class=first.outside_class, released_gains=first.released_gains,
                   **carried(first))
    hot = tuple(dict.fromkeys(tuple(hot) + tuple(m.f0 for m in discrepancy)))
    points = points_stage(cfg, case, WIDEN, hot, log)
    base = baseline_stage(cfg, case, points, seed, log)
    level_bound = level_stage(base, nonlin, log)
    sel, base = selection_stage(cfg, case, points, base, level_bound, seed, opts, log)
    case, sel.state = confirmed_gains(case, points, sel.state, base.nu, base.n_fit, log)
    gone = refuted_on_wider(sel, base.held) if seed is not None else None
    sel.unconfirmed += [gone] if gone else []
    return conclude(cfg, case, points, base, sel, nonlin, level_bound, None, log)


def widen_stage(cfg, case, points, base, sel, nonlin, opts, log):
    """The widened look's Conclusion when the first look's windows miss the mismatch and
    the wider look stands; None when the first look stands."""
    advance("diagnose", "widen")
    if off_peak(base, sel):
        if budget_spent("the widened look"):
            return None
        log("the mismatch lives in the held-out shoulders more than in the fitted windows: "
            "widening the windows 3x and looking again")
        hot = unexplained(case, points.base, base.res.z, points.fit)[1]
        return widened_look(cfg, opts, nonlin, hot, None, log, case)
    state = sel.state
    if not leaves_shoulders(base, sel, state["problem"].params.n_z - points.base.params.n_z) \
            or budget_spent("the widened look"):
        return None
    # what remains lies between the windows (an appendage's resonance reported as an
    # extra mode with no window on it, or later rounds' candidates worsening shoulders
    # they cannot fit): the wider look stands if it keeps every finding of this one
    log(f"the findings leave the held-out shoulders at {state['held']:.2f}: widening the "
        "windows 3x and looking again")
    extra, hot = unexplained(case, state["problem"], state["z"], points.fit)
    seed = Seed(base.res.z, state["z"], [r["enrichment"] for r in sel.found])
    wide = widened_look(cfg, opts, nonlin, tuple(dict.fromkeys(tuple(hot) + tuple(extra))),
                        seed, log, case)
    if keeps_findings(wide.result, sel.found):
        return wide
    log("the wider look loses a finding of the first: the first look stands")
    return None


def conclude(cfg, case, points, base, sel, nonlin, level_bound, screening, log):
    """Checks of the final model and the verdict of one look."""
    if sel.found:   # the joints' bend judged again with the findings in
        case, points, base, sel.state = final_sweep(case, points, base, sel.state, log,
                                                    refit_from(cfg, log))
    checks = checks_stage(cfg, case, points, base, sel, level_bound, log)
    advance("diagnose", "verdict")
    return verdict_stage(cfg, case, points, base, sel, checks, nonlin, level_bound,
                         screening, log)


# ------------------------------------------------------------------ stages
def points_stage(cfg, case, widen, hot, log):
    """The fitted windows (widen x the case's half-power bandwidths, plus windows at the
    hot frequencies), the held-out shoulders (3x wider, not fitted), and the target."""
    advance("diagnose", "points" if widen == 1 else "points (widened look)")
    fit = fit_windows(cfg, case, widen)
    held = np.setdiff1d(fit_windows(cfg, case, 3 * widen), fit)
    if held.size == 0:  # held-out tests need points no fit used (hot windows too: else NaN)
        fit = np.intersect1d(fit_windows(cfg, case, widen, windows=True), case.selected)
        held = np.setdiff1d(case.selected, fit)
        log(f"the case fits every frequency: the diagnosis fits its half-power windows ({fit.size} "
            f"points) and holds out the other {held.size}")
    if hot:
        fit, held = hot_windows(cfg, case, fit, held, hot, log)
        held = np.setdiff1d(held, fit)
    sig_fit, sig_held = noise_sigma(case, fit), noise_sigma(case, held)
    target = fit_target(case, fit, sig_fit)
    base = diagnosis_problem(case, target)
    check_start_residuals(case, base)
    return Points(widen, fit, held, sig_fit, sig_held, target, base, tuple(hot))


def baseline_stage(cfg, case, points, seed, log, starts=None):
    """The case's own model at its optimum: a scatter search, or (seeded) a solve from
    the first look's optima, or from the given starts (with the model discrepancy)."""
    advance("diagnose", "baseline", step=starts is None)
    pr = points.base
    if starts is not None:
        res = step("baseline", fingerprint(points.fit, *starts), lambda: best_fit(pr, starts))
        converged = bool(res.success)
    elif seed is None:
        sc = cfg.search
        res, converged = step("baseline", fingerprint(points.fit, points.widen), lambda: scatter_best(
            pr, SearchConfig(starts=max(sc.starts, BASELINE_STARTS), seed=sc.seed,
                             workers=sc.workers, executor=sc.executor, scheduler=sc.scheduler),
            setup=Setup(diagnosis_problem, case, points.target, value=pr)))
    else:
        # the first look searched this model already; over 3x the points a search costs
        # about what the whole first look did, and a local minimum left here is caught by
        # the re-solve from the refits' optima (refit.repolish)
        res = step("baseline", fingerprint(points.fit, seed.z_base, seed.z_final),
                   lambda: best_fit(pr, [seed.z_base, seed.z_final[:pr.params.n_z]]))
        converged = bool(res.success)
    if not converged:
        log("baseline: no start met the solver's convergence test (iteration limit); the "
            "lowest objective reached is used")
    n_fit = pr.n_used
    chi = 2 * res.f
    nu = max(n_fit - pr.params.n_z, 1)
    cells, _, rh0 = residual_map(case, pr, res.z, points.fit, points.held, points.sig_fit,
                                 points.sig_held)
    held = float(np.mean(rh0 ** 2))
    # errors shared between channels and neighbouring bins: a right noise model's
    # reduced chi-square strays from 1 by this much on these points (diagnosis.spread)
    sd, n_eff = chi2_spread(signed(pr, res.z, case, points.fit, points.sig_fit), points.fit)
    log(f"baseline: reduced chi-square {chi / nu:.2f} on {n_fit} fitted points "
        f"(a right noise model gives 1 +- {sd:.2f} here: {n_eff:.0f} effective independent "
        f"points), held-out {held:.2f} on {rh0.size} points")
    log("  " + describe_noise(case.noise)["statement"])
    return Baseline(res, converged, chi, nu, n_fit, held, cells, (sd, n_eff))


def refit_from(cfg, log):
    """refit(case, points, z): the baseline solved from z, for the stages that change the
    data or the model's nuisances (nlp.diagnosis.sweep, nlp.diagnosis.gains)."""
    return lambda c, p, z: baseline_stage(cfg, c, p, None, log, starts=[z])


def reduced_stage(cfg, case, points, base, log):
    """(case, points, baseline) on a reduced basis re-centred on the baseline's optimum
    (nlp.diagnosis.reduction): a basis at the nominal model would bias every fit."""
    def refit(c, z):
        return (pr := diagnosis_problem(c, points.target)), best_fit(pr, [z])

    centre, z = step("reduced basis", fingerprint(points.fit, base.res.z),
                     lambda: recentre_baseline(case, refit, base.res.z, log)[1:3])
    case = replace(case, basis_centre=centre)  # the last problem's basis is cached: no rebuild
    points = replace(points, base=diagnosis_problem(case, points.target))
    return case, points, baseline_stage(cfg, case, points, None, log, starts=[z])


def discrepancy_stage(cfg, case, points, base, widen, log):
    """(case, points, baseline) with the model discrepancy (nlp.diagnosis.discrepancy): the
    resonances the baseline lacks in the band that no catalogue family explains, as modal
    terms in every later fit, with windows on them; unchanged when there are none."""
    advance("diagnose", "discrepancy")
    modes = extra_modes_in_band(case, points, base)
    if not modes or budget_spent("the model discrepancy"):
        return case, points, base
    hot = tuple(m.f0 for m in modes)
    log("resonances the model lacks in the band: " + ", ".join(f"{f:.2f} Hz" for f in hot)
        + ": is each one a catalogue family's, or model discrepancy?")
    wide = points_stage(cfg, case, widen, hot, log)
    # kept as a step: on a torsional frame this stage alone has taken a quarter of an hour
    n_own = own_modes_in_band(case, points.base, base.res.z).size
    kept, z0, untested, outside = logged_step(
        "discrepancy", fingerprint(wide.fit, base.res.z, hot, n_own),
        lambda lg: kept_discrepancy(case, wide, base.res.z, modes, lg, budget_over, n_own), log)
    if untested:
        budget_note("the families' test of the resonances at " + ", ".join(
            f"{f:.2f}" for f in untested) + " Hz (kept as model discrepancy)")
    if not kept:
        return case, points, base
    case = replace(case, discrepancy=tuple(modes[i] for i in kept), outside_class=outside)
    points = points_stage(cfg, case, widen, hot, log)
    return case, points, baseline_stage(cfg, case, points, None, log, starts=[z0])


def level_stage(base, nonlin, log):
    """Whether the structure is nonlinear (level-dependent, or a story stiffer one way) and
    the linear model misses the reference level by more than LEVEL_MISFIT: then no linear
    candidate is searched on it."""
    level_bound = bool(nonlin and (nonlin["found"] or nonlin.get("asymmetric"))
                       and max(base.chi / base.nu, base.held) > LEVEL_MISFIT)
    if level_bound:
        log(f"the structure is nonlinear and the reference level's reduced chi-square is "
            f"{base.chi / base.nu:.0f} (held-out {base.held:.0f}): linear candidates are not "
            "searched on it")
    return level_bound


def selection_stage(cfg, case, points, base, level_bound, seed, opts, log):
    """Forward selection over rounds of candidate refits; returns the Selection and the
    baseline (re-solved when a refit's optimum showed it was a local minimum)."""
    advance("diagnose", "selection")
    sel = Selection(state={"current": [], "z": base.res.z, "chi": base.chi,
                           "held": base.held, "problem": points.base})
    if level_bound or case.outside_class:
        return sel, base
    others = setup_others(cfg, case.discrepancy, log)
    sel.reciprocity = reciprocity_of_tests(cfg, case.f[points.fit]) if cfg.data.tests else \
        reciprocal_pairs(case, others, points.fit)
    for pr in sel.reciprocity:
        log(f"reciprocity with {pr['test']}: gain of {pr['channel_q']} over {pr['channel_p']} "
            f"{math.exp(pr['ln_ratio']):.3f} +- {100 * pr['se']:.1f} % (model-free, "
            f"{pr['windows']} windows)")
    rnd, repolished = 0, 0
    while rnd < opts.max_findings:
        if adequate(sel.state["chi"], base.nu, sel.state["held"]) and rnd > 0 or \
                budget_spent(f"selection round {rnd + 1}"):
            break
        advance("diagnose", f"selection, round {rnd + 1} of at most {opts.max_findings}",
                step=False)
        jobs = round_jobs(case, points, sel, others, seed, rnd, opts.top)
        state = sel.state
        results = refits_step(
            fingerprint(rnd, state["z"], [(sc, repr(e)) for sc, e in jobs]),
            lambda: refit_all([(case, points.target, state["current"], state["z"], e, sc,
                                base.n_fit, points.held, points.sig_held) for sc, e in jobs],
                              cfg.search), case, points.target, state["current"])
        better = repolish_step(fingerprint(state["z"], [r["chi2"] for r in results]),
                               lambda: repolish(state, results, case, points.held,
                                                points.sig_held, base.n_fit),
                               state["problem"]) if repolished < MAX_REPOLISH else None
        if better is not None:
            # the current optimum was a local minimum: judge the candidates against the
            # better one, so a refit that merely finds the current model's own minimum
            # is not taken for evidence
            log(f"  [{rnd + 1}] the current model re-solved from a candidate's optimum reaches "
                f"chi-square {better['chi']:.1f} (was {state['chi']:.1f}): repeating the round")
            repolished += 1
            if not state["current"]:
                base = _repolished_baseline(case, points, base, better)
            better.pop("result", None)
            sel.state = better
            continue
        accepted = judge_round(case, points, base, sel, others, results, rnd, log)
        if not accepted or not adopt(case, points, sel, others, results, accepted, log):
            break
        rnd += 1
    if len(sel.found) > 1:
        sel.found, sel.state = prune(case, points.target, sel.found, sel.state, base.n_fit,
                                     points.held, points.sig_held, log)
    return sel, base


def _repolished_baseline(case, points, base, better):
    """The baseline at the re-solved optimum of the case's own model."""
    res = better.pop("result")
    cells, _, _ = residual_map(case, points.base, res.z, points.fit, points.held,
                               points.sig_fit, points.sig_held)
    return Baseline(res, bool(res.success), better["chi"], base.nu, base.n_fit, better["held"],
                    cells, base.spread, base.before)


def round_jobs(case, points, sel, others, seed, rnd, top):
    """The (score, candidate) pairs refitted in round rnd: the best by score, appendages
    at the hot frequencies, those the other tests rank high; in a seeded look, the first
    look's finding of this round alone. Sets sel.absorbed in the first round."""
    state, target, hot = sel.state, points.target, points.hot
    current, z = state["current"], state["z"]
    pairs = [(e, score(case, target, current, z, e))
             for e in candidates(case) if not same(e, current)]
    extra = unexplained(case, state["problem"], z, points.fit)[0]
    pairs += scan_secondary(case, target, current, z, resonances=extra + tuple(hot))
    if rnd == 0:
        sel.absorbed = [(e, kept) for e, (_, kept) in pairs if kept < ABSORBED]
    at_hot = hot_appendages(case, target, current, z, hot, extra + tuple(hot))
    scored = sorted(((sc, e) for e, (sc, _) in pairs + at_hot), key=lambda t: -t[0])
    jobs = to_refit(scored, top)
    have = {repr(e) for _, e in jobs}
    jobs += [(sc, e) for e, (sc, _) in at_hot if repr(e) not in have]
    if others:
        jobs = refits_of_others(others, state, jobs, {repr(e): sc for sc, e in scored}, top)
    if seed is not None and rnd < len(seed.found):
        # the first look chose this finding over its rivals in this round; here it is
        # only re-proven on the wider points (the same tests), the rest comes after
        e = seed.found[rnd]
        jobs = [(score(case, target, current, z, e)[0], e)]
    return jobs


def judge_round(case, points, base, sel, others, results, rnd, log):
    """Evidence of one round's refits (decide); the accepted candidates that hold on the
    other tests, best first."""
    state = sel.state
    k_cur = state["problem"].params.n_z - points.base.params.n_z
    sel.phis.append(hold_open_nuisance(results, lambda rs: decide(
        rs, state["chi"], state["held"], base.nu - k_cur, base.n_fit,
        n_held=points.held.size * len(case.channels)), (case, points.target, state["current"],
        state["z"], base.n_fit, points.held, points.sig_held), log))
    for r in results:
        log(f"  [{rnd + 1}] {r['physics']} {r['location']}: score {r['score']:.1f}, "
            f"dBIC {r['delta_bic']:.1f} (phi {r['phi']:.2f}), held-out {r['held_out']:.2f}"
            f"{' (accepted)' if r['accepted'] else ' [' + why_refused(r) + ']'}")
    refute_gains(sel, results, log)
    refute_in_discrepancy(case.discrepancy, results, log)
    sel.tried += results
    accepted = sorted([r for r in results if r["accepted"]], key=evidence)
    if others and accepted:
        accepted, rejected, recs = hold_on_others(others, state, accepted, log)
        sel.unconfirmed += rejected
        sel.consistency += recs
    return accepted


def adopt(case, points, sel, others, results, accepted, log):
    """Add the best accepted candidate to the model; False (stop) when candidates tie."""
    state = sel.state
    best = accepted[0]
    sel.unresolved += better_unresolved(results, best, state["held"])
    ties = tied(accepted)
    if ties:
        # physically different candidates the data cannot tell apart: name them all,
        # add none (a further effect after a finding is reported the same way)
        sel.indistinct = [best] + ties
        sel.alternatives += accepted
        return False
    if best["problem"] is None or not best["converged"]:  # rebuilt without the cap
        best["problem"] = diagnosis_problem(case, points.target,
                                        state["current"] + [best["enrichment"]], optimize=False)
    if not best["converged"]:
        continue_refit(best, case, points.held, points.sig_held, log)
    sel.found.append(best)
    sel.alternatives += accepted[1:]
    for o in others:
        o["at"][tuple(repr(e) for e in state["current"] + [best["enrichment"]])] = \
            best["there"][o["label"]]
    sel.state = {"current": state["current"] + [best["enrichment"]], "z": best["z"],
                 "chi": best["chi2"], "held": best["held_out"], "problem": best["problem"]}
    return True


def checks_stage(cfg, case, points, base, sel, level_bound, log):
    """The final model beyond its windows: inside the model class, phase, loss, the whole
    band; and the other tests' records of the final findings."""
    advance("diagnose", "checks")
    state = sel.state
    phase = loss = None
    # a linear fit that far off, or a model without a class of motion the data show, says
    # nothing about priors, dampers, phase
    if level_bound or case.outside_class:
        inside = {"findings": [], "parameter_changes": [], "damping": None, "absorbed": [],
                  "parameters": []}
    else:
        inside = inside_model_class(cfg, case, state, sel.absorbed, log)
        phase = phase_check(case, state, np.union1d(points.fit, points.held), log)
        if phase:
            inside["findings"] += phase["findings"]
        loss = loss_check(case, state, phase, log)
        if loss:
            inside["findings"] += loss["findings"]
    inside["findings"] = list(case.released_gains) + inside["findings"]
    consistency, unconfirmed = final_records(sel)
    whole = whole_band(case, points.base, base.res.z, state["problem"], state["z"], points.fit)
    alone = []
    if cfg.data.tests and sel.found:
        log("each test alone, with the joint findings:")
        alone = alone_fits(cfg, case, case.f[points.fit], sel.found, state, log,
                           sel.reciprocity)
    return Checks(inside, phase, loss, whole, consistency, unconfirmed, alone)
