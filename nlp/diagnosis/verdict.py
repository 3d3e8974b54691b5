"""The verdict of a look: adequate, setup_error, missing_physics, partly_explained or ambiguous.

The verdict and diagnosis.json are built from the stages' data (nlp.diagnosis.look);
ambiguous verdicts name the measurement that would separate the candidates (SUGGESTIONS).
"""

import os
import textwrap

from nlp.diagnosis.checkpoint import budget_report
from nlp.diagnosis.decide import ADEQUATE_HELD, adequate, where
from nlp.diagnosis.gains import calibration_summary
from nlp.diagnosis.discrepancy import beyond_band, class_statement, described
from nlp.diagnosis.evidence import BIC_TIE, undetermined
from nlp.diagnosis.fitting import case_references, residual_map
from nlp.diagnosis.joint import between_tests
from nlp.diagnosis.level_kind import outside
from nlp.diagnosis.locations import is_fe
from nlp.diagnosis.look import Conclusion
from nlp.diagnosis.plain import beyond_fit, finding_line, finding_title, finding_values, \
    held_words, hypotheses, other_statements, paragraph, unconfirmed_lines, finding_note, \
    EXTRA_MODES, REFERENCES, REFIT_STATEMENT, REMAINING, REST_HEAD
from nlp.diagnosis.plots import plot_diagnosis
from nlp.frf.noise import describe as describe_noise
from nlp.output.provenance import provenance
from nlp.output.results import write_json

SUGGESTIONS = {
    "added_mass": "weigh the floor, or repeat the test with a known added mass",
    "base_flexibility": "a sensor on the base (table) to measure the base motion directly",
    "secondary_oscillator": "a sensor on the suspected appendage, or a shaker at another floor",
    "local_damper": "a second excitation level or a wider frequency band around the higher modes",
    "hysteretic_damping": "the phase of the FRFs over a wide band (viscous and hysteretic loss "
                          "differ in phase off resonance)",
    "nonadjacent_coupling": "a second shaker position (force at another floor)",
    "frame_action": "the frame's drawings (beam and column sizes), or a second shaker position",
    "sensor_gain": "a calibration check of that sensor, or a second sensor on the same floor",
    "sensor_delay": "the phase of the FRFs (complex residual) or a check of the acquisition timing",
    "nonlinearity": "the same test at a second excitation level",
}

# what would tell apart the rest of a partly explained mismatch: with resonances the
# model lacks, sensors that see the motions a planar model cannot have; without, another
# view of the same structure
REST_SUGGESTIONS = {
    True: ["accelerometers in the other horizontal direction and at two corners of a floor "
           "(out-of-plane and torsional modes show there)"],
    False: ["a second shaker position (a force at another floor), diagnosed jointly with "
            "this test"]}

WORDS = {"added_mass": "an unmodelled mass", "base_flexibility": "a flexible base",
         "secondary_oscillator": "a secondary oscillator (appendage)",
         "local_damper": "a concentrated damper", "hysteretic_damping": "hysteretic damping",
         "nonadjacent_coupling": "a stiffness coupling (non-shear behaviour)",
         "frame_action": "frame action (flexible beams: not a shear building)",
         "sensor_gain": "a sensor gain error", "sensor_delay": "a sensor time delay"}


def statement(r):
    """One sentence naming a finding r (public form): family, location, values."""
    loc = r["location"]
    if "where" in loc:      # an FE model's place in its own terms (locations.located)
        where = loc["where"]
    elif "floor" in loc:
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
    if r.get("not_determined"):
        pars += "; not determined by the data: " + ", ".join(r["not_determined"])
    if r.get("held"):
        pars += "; " + "; ".join(held_words(r["physics"], r["held"],
                                            stated=r.get("held_reference")))
    return f"{REFIT_STATEMENT}{WORDS[r['physics']]} {where} ({pars})."


def public(r):
    """A refit result as diagnosis.json reports it: values, errors, evidence, statement."""
    d = {k: r[k] for k in ("physics", "location", "parameters", "uncertainty")}
    names = list(r["parameters"])
    open_ = undetermined(r["physics"], names, [r["parameters"][n] for n in names],
                         [r["uncertainty"][n] for n in names])
    if open_:
        # reported without a value: its error exceeds it (nlp.diagnosis.evidence.NUISANCE)
        d["parameters"] = {n: v for n, v in r["parameters"].items() if n not in open_}
        d["uncertainty"] = {n: v for n, v in r["uncertainty"].items() if n not in open_}
        d["not_determined"] = open_
    if r.get("held"):
        # an assumption, not an estimate: no error (nlp.diagnosis.nuisance)
        d["held"] = dict(r["held"])
        if r.get("held_reference"):
            d["held_reference"] = dict(r["held_reference"])
    d["evidence"] = {"score": r["score"], "delta_bic": r["delta_bic"], "chi2": r["chi2"],
                     "held_out_chi2": r["held_out"], "phi": r.get("phi", 1.0),
                     "raw_delta_chi2": r.get("raw_delta_chi2"),
                     "significant": r.get("significant", True),
                     "held_out_excess": r.get("held_excess"),
                     "converged": r.get("converged", True)}
    if r.get("correlation_factor"):
        d["evidence"]["correlation_factor"] = r["correlation_factor"]
        d["evidence"]["delta_bic_correlated"] = r.get("delta_bic_correlated")
    if r.get("split"):
        d["evidence"]["resolution"] = r["split"]
    if r.get("widened"):   # refuted by the widened look (nlp.diagnosis.widen)
        d["evidence"]["widened_look"] = r["widened"]
    d["statement"] = statement(d)
    return d


# families that describe the test set-up (a channel's calibration or timing), not the structure
SETUP_FAMILIES = ("sensor_gain", "sensor_delay")


def setup_only(found):
    """Whether every finding (at least one) is of the set-up, none of the structure."""
    return bool(found) and all(f["physics"] in SETUP_FAMILIES for f in found)


def classify(confirmed, unconfirmed, indistinct, nonlin, inside, adequate, remaining=False,
             discrepancy=False):
    """The verdict. Candidates that cannot be told apart, or findings that do not hold
    on the case's other tests, with nothing else found, make it "ambiguous": an
    inadequate model is said so, never turned into one confident finding. (Ties after
    a confirmed finding are reported as what remains, next to it.) Findings that leave
    the final model's misfit above what the noise model allows (remaining) make it
    "partly_explained": what was found is named, the rest is mapped, not claimed. So does
    model discrepancy (resonances the model class cannot have): the model is incomplete
    in a way no candidate family describes. nonlin: a named level dependence, True or
    level_kind.outside's word; a change of mass or damping ("outside") is named and placed
    but no family describes it (partly_explained), and one whose kind the data cannot tell
    ("undecided") makes it ambiguous. Findings of the set-up only (a channel's gain or
    delay) that leave nothing else make it "setup_error": the structural model is right and
    the case's sensors are not as it says, which an engineer fixes in the case, not in the
    model."""
    if (indistinct or unconfirmed) and not confirmed and not nonlin and not inside:
        return "ambiguous"
    # a level dependence whose mechanism is not the family's stiffness (level_kind.outside)
    beyond = nonlin in ("outside", "undecided")
    if confirmed or inside:
        if remaining or discrepancy or beyond:
            return "partly_explained"
        return "setup_error" if not nonlin and setup_only(list(confirmed) + list(inside)) \
            else "missing_physics"
    if nonlin:
        return {"outside": "partly_explained", "undecided": "ambiguous"}.get(nonlin,
                                                                          "missing_physics")
    if discrepancy:
        return "partly_explained"
    return "adequate" if adequate else "ambiguous"


# a channel x band cell of the final model's whole-band map is part of what is left when
# its mean squared normalised residual exceeds this: the held-out adequacy level
# (decide.ADEQUATE_HELD), the misfit a model that explains its shoulders stays under
LEFT_CHI2 = ADEQUATE_HELD
MAX_LEFT_CELLS = 6      # the worst cells named in the summary; diagnosis.json keeps them all


def mismatch_left(whole):
    """Where the final model still misses the data: the whole band's channel x band cells
    above LEFT_CHI2 (worst first) and the resonances the model lacks."""
    if not whole:
        return {"cells": [], "extra_modes": [], "fitted_band_hz": None}
    fitted = [c["band_hz"] for c in whole["map"]["after"] if c.get("fitted_points")]
    span = [min(b[0] for b in fitted), max(b[1] for b in fitted)] if fitted else None
    # the misfit the fit was asked to remove comes first; beyond the fitted band the model
    # was never fitted, so a misfit there says less about what it lacks
    cells = sorted((c for c in whole["map"]["after"] if c["chi2"] > LEFT_CHI2),
                   key=lambda c: (beyond_fit(c, span), -c["chi2"]))
    return {"cells": cells, "extra_modes": whole["extra_modes"], "fitted_band_hz": span}


def left_statement(left):
    """One sentence: where the rest of the mismatch sits (channels x bands)."""
    cells = left["cells"][:MAX_LEFT_CELLS]
    if not cells:
        return None
    span = left.get("fitted_band_hz")
    return (REST_HEAD + "; ".join(
        f"{c['channel']} at {c['band_hz'][0]:.1f}-{c['band_hz'][1]:.1f} Hz ({c['chi2']:.3g} x "
        "the noise" + (", beyond the fitted band)" if beyond_fit(c, span) else ")")
        for c in cells) + " (mean squared misfit over the noise, whole band).")





def _fit_summary(base, state, k, nonlin_found, nonlin, found):
    """fit.before and fit.after of diagnosis.json: chi-squares of the baseline and of the
    final model (k more parameters); for a nonlinearity named alone, the other level's
    held-out misfit with each level's model."""
    nu = base.nu
    fit_before = {"objective": base.res.f, "reduced_chi2": base.chi / nu,
                  "held_out_chi2": base.held, "converged": base.converged,
                  "reduced_chi2_sd": base.spread[0], "effective_points": base.spread[1]}
    fit_after = {"objective": state["chi"] / 2, "reduced_chi2": state["chi"] / max(nu - k, 1),
                 "held_out_chi2": state["held"]}
    if nonlin_found and not found and "held_out" in nonlin:
        before_o, after_o = nonlin["held_out"]
        fit_before["other_level_held_out_chi2"] = before_o
        fit_after = dict(fit_before, other_level_held_out_chi2=after_o)
    return fit_before, fit_after


def _suggestions(cfg, case, verdict, sel, unconfirmed, remaining, nonlin_found, extra=()):
    """The measurements that would separate the candidates or settle what remains."""
    suggestions = []
    if verdict == "ambiguous":
        group = sel.indistinct or unconfirmed or sel.tried[:2]
        suggestions = list(dict.fromkeys(SUGGESTIONS[r["physics"]] for r in group))
    if remaining:
        suggestions += REST_SUGGESTIONS[bool(extra)]
    if not nonlin_found and not cfg.data.level_files and (verdict == "ambiguous" or remaining):
        suggestions.append(SUGGESTIONS["nonlinearity"] + " (to rule out nonlinearity)")
    if not describe_noise(case.noise)["measured"]:
        suggestions.append("store the coherence and the number of averages with the FRF"
                           if case.records is None else
                           "record a quiet stretch before and after the excitation")
    return suggestions


def _level_statements(base, found, level_bound):
    """The named nonlinearities first; for a level-bound case, why nothing linear is judged."""
    out = [f["statement"] for f in found]
    if level_bound:
        out.append(f"No linear model fits the reference level (reduced chi-square "
                   f"{base.chi / base.nu:.1f}, {base.held:.1f} on the held-out shoulders): the "
                   "nonlinearity acts there too, so no linear candidate, prior or "
                   "damper is judged on it.")
    return out


def _tie_statements(sel):
    """Candidates that cannot be told apart, and better ones the data cannot resolve."""
    out = []
    indistinct = sel.indistinct
    if indistinct:
        phi = indistinct[0].get("phi", 1.0)
        out.append(
            "The model is inadequate here, and these candidates cannot be told apart: "
            + "; ".join(f"{where(r)} (dBIC {r['delta_bic']:.1f})" for r in indistinct)
            + f" (within {BIC_TIE:g} of each other in BIC with the chi-square divided by the "
            f"remaining misfit, phi = {phi:.1f}, and alike on the held-out points)."
            + (" They are candidates for what remains after the findings above."
               if sel.found else ""))
    for r in sel.unresolved:
        sp = r["split"]
        out.append(
            f"{where(r)} explains the data better than {r['instead_of']} (dBIC "
            f"{r['delta_bic']:.1f}, held-out {r['held_out']:.2f}), but its mode at "
            f"{sp['appendage_mode_hz']:.3f} Hz lies {sp['separation_hz']:.3f} Hz from the mode at "
            f"{sp['nearest_mode_hz']:.3f} Hz, inside their half-power bands or the resolution: the data "
            f"do not show it as a resonance of its own, so it is not named, and "
            f"{r['instead_of']} may stand in for it.")
    return out


def _unconfirmed_statements(cfg, unconfirmed, verdict):
    """Findings that do not hold on another test of the structure."""
    out = []
    for r in unconfirmed:
        if r.get("widened"):
            w = r["widened"]
            out.append(f"{statement(public(r))[:-1]} when refitted on windows 3x wider (the "
                       f"first look found it on the half-power windows), but there it predicts "
                       f"the held-out shoulders worse than the model without it (held-out "
                       f"chi-square {w['held_out']:.3g} against {w['held_out_without']:.3g}). "
                       "It is not accepted.")
        for c in (c for c in r.get("records", []) if not c["holds"]):
            there = ", ".join(f"{n} = {v:.4g} +- {c['there_uncertainty'][n]:.2g}"
                              for n, v in c["there"].items())
            out.append(
                f"{statement(r)[:-1]} on {os.path.basename(cfg.data.file)}, but it does not hold on "
                f"{c['test']} ({there}): {c['reason']}. It is not accepted.")
    if unconfirmed and verdict == "ambiguous":
        out.append("The model is inadequate here: no candidate holds on every test of "
                   "this structure, so none can be named (not confirmed by the other "
                   "tests: "
                   + "; ".join(where(r) for r in unconfirmed) + ").")
    return out


def _budget_statement(budget):
    """Where the diagnosis stopped at its time budget (nlp.diagnosis.checkpoint)."""
    return (f"The diagnosis stopped at its time budget of {budget['minutes']:.3g} minutes, "
            f"before {' and '.join(budget['stopped_before'])}: what is reported was decided, "
            "but the candidates and looks after that point were not tried, so more may be "
            "missing than is said here.")


def _closing_statements(verdict, sel, unconfirmed, remaining, inside, whole, extra,
                        budget=None):
    """What remains unexplained, parameter changes and extra modes (those not reported as
    model discrepancy); where a time budget stopped the search."""
    out = [_budget_statement(budget)] if budget else []
    if remaining:
        out.append(REMAINING)
        st = left_statement(mismatch_left(whole))
        if st:
            out.append(st)
    if verdict == "ambiguous" and not sel.found and not sel.indistinct and not unconfirmed:
        out.append("The model does not explain the data within the noise, and no "
                   + ("candidate tried before the budget ran out explains the mismatch."
                      if budget else "candidate family explains the mismatch."))
    for o in inside["parameter_changes"]:
        out.append(o["statement"])
    if extra:
        out.append(EXTRA_MODES + "; ".join(
            f"{e['frequency_hz']:.2f} Hz (seen by {', '.join(e['channels'])})"
            for e in extra) + ".")
    return out


def _alternatives(found, alternatives):
    """Accepted candidates not adopted, best first, one per family and location."""
    alts, seen = [], {(r["physics"], repr(r["location"])) for r in found}
    for r in sorted(alternatives, key=lambda r: r["delta_bic"]):
        key = (r["physics"], repr(r["location"]))
        if key not in seen:
            seen.add(key)
            alts.append(r)
    return alts


def _joint_statements(nonlin, nonlin_found):
    """A level dependence not shown to exceed what real frames' joints do is said, not found."""
    band = (nonlin or {}).get("joint_band")
    if nonlin_found or not band or band["material"]:
        return []
    d = f"{100 * band['delta']:.0f} %"
    if band.get("within", True):
        return [f"The excitation levels do not share one linear model exactly, but changes of "
                f"at most {d} in each story stiffness and floor mass between the levels explain "
                f"the difference (within BIC's price), as the joints of real frames do; this is "
                f"not reported as a nonlinearity."]
    return [f"The excitation levels do not share one linear model exactly; whether the "
            f"difference exceeds changes of {d} in each story stiffness and floor mass (what the "
            f"joints of real frames do) is not decided, because the refit that asks it did not "
            f"converge, so no nonlinearity is reported."]


def _optional_parts(result, screening, checks, nonlin, nonlin_found):
    """The screening, phase and loss checks and the level comparison, when they were made."""
    if screening is not None:
        result["screening"] = screening
    if checks.phase is not None:
        result["phase_check"] = checks.phase["channels"]
    if checks.loss is not None:
        result["loss_check"] = {k: v for k, v in checks.loss.items() if k != "findings"}
    if (nonlin or {}).get("asymmetry") is not None:
        result["asymmetry"] = nonlin["asymmetry"]
    if nonlin is not None and nonlin.get("levels", True):
        # written whether or not a nonlinearity was named, so a miss can be read from the file
        result["level_comparison"] = {"found": nonlin_found, "max_z": nonlin["max_z"],
                                      "shared_stiffness": nonlin.get("shared_stiffness"),
                                      "harmonics": nonlin.get("harmonics"),
                                      "joint_band": nonlin.get("joint_band"),
                                      "not_compared": nonlin.get("not_compared", [])}


def verdict_stage(cfg, case, points, base, sel, checks, nonlin, level_bound, screening, log):
    """The verdict of one look and its diagnosis.json (a Conclusion; not yet written)."""
    state, found, inside = sel.state, sel.found, checks.inside
    unconfirmed = checks.unconfirmed
    nonlin_found = bool(nonlin and nonlin["found"])
    improved, z_imp = state["problem"], state["z"]
    k = improved.params.n_z - points.base.params.n_z
    b0 = base.before or base   # the model with every gain inside the calibration tolerance
    remaining = (bool(found) or bool(inside["findings"])) and not adequate(
        state["chi"], max(base.nu - k, 1), state["held"])
    disc = described(improved, z_imp, case.discrepancy) if case.discrepancy else []
    asym = (nonlin or {}).get("asymmetric")
    verdict = classify(found, unconfirmed, sel.indistinct,
                       "outside" if asym else nonlin_found and outside(nonlin["found"]),
                       inside["findings"],
                       adequate(b0.chi, b0.nu, b0.held), remaining, bool(disc))
    # resonances beyond the fitted band do not judge the fit inside it (the verdict above);
    # they are reported as model discrepancy, not as extra modes
    whole = checks.whole
    extra, beyond = beyond_band(case, improved, z_imp, whole["extra_modes"] if whole else [])
    disc += beyond
    cells_after, _, _ = residual_map(case, improved, z_imp, points.fit, points.held,
                                     points.sig_fit, points.sig_held)
    fit_before, fit_after = _fit_summary(b0, state, k, nonlin_found, nonlin, found)
    findings = [public(r) for r in found] + inside["findings"]
    statements = [f["statement"] for f in findings]
    named = ([nonlin["found"]] if nonlin_found else []) + ([asym] if asym else [])
    findings[:0] = named
    statements[:0] = _level_statements(base, named, level_bound) if named else []
    suggestions = _suggestions(cfg, case, verdict, sel, unconfirmed, remaining, nonlin_found,
                               extra + beyond)
    statements += [d["statement"] for d in disc] + class_statement(case, disc)
    statements += _joint_statements(nonlin, nonlin_found)
    statements += _tie_statements(sel)
    statements += _unconfirmed_statements(cfg, unconfirmed, verdict)
    budget = budget_report()
    statements += _closing_statements(verdict, sel, unconfirmed, remaining, inside, whole, extra,
                                      budget)
    if budget:
        suggestions.append("run again with --resume and a larger --budget: the finished steps "
                           "are kept")
    alts = _alternatives(found, sel.alternatives)
    result = {"case": cfg.name, "case_file": cfg.path, "verdict": verdict, "findings": findings,
              "alternatives": [public(r) for r in alts],
              "indistinguishable": [public(r) for r in sel.indistinct],
              "unconfirmed": [public(r) for r in unconfirmed],
              "unresolved_better": [dict(public(r), instead_of=r["instead_of"])
                                    for r in sel.unresolved],
              "consistency": checks.consistency,
              "tests_alone": checks.tests_alone,
              "between_tests": between_tests(checks.tests_alone),
              "absorbed": inside["absorbed"],
              "parameter_changes": inside["parameter_changes"],
              "fitted_parameters": inside["parameters"],
              "damping_decomposition": inside["damping"],
              "summary": statements, "remaining_mismatch": remaining,
              "model_discrepancy": disc, "outside_model_class": case.outside_class,
              "mismatch_left": mismatch_left(checks.whole) if remaining else None,
              "evidence_scale": {"phi": sel.phis[0] if sel.phis else 1.0},
              "fit": {"before": fit_before, "after": fit_after},
              "residual_map": {"before": b0.cells, "after": cells_after},
              "whole_band": whole,
              "extra_modes": extra,
              "suggested_measurements": suggestions, "noise": describe_noise(case.noise),
              "calibration": calibration_summary(case, sel.state["problem"], sel.state["z"]),
              "sweep_joints": case.sweep_joints,
              "provenance": provenance(cfg)}
    _optional_parts(result, screening, checks, nonlin, nonlin_found)
    if budget:
        result["budget"] = budget
    log_conclusion(log, result, physical_references(case))
    return Conclusion(result, case, points.base, base.res.z, improved, z_imp, base.cells,
                      cells_after, " + ".join(r["physics"] for r in found) if found else None)


def physical_references(case):
    """The magnitudes the families' parameters are scaled by (mean floor mass [kg], story
    stiffness [N/m], damping [N s/m]): an appendage's mass ratio times m_ref is its mass;
    "rayleigh": whether the model's damping is a Rayleigh law, "channel_masses": whether
    m_ref is the mean mass at the channels' DOFs, on an FE model without node coordinates
    (units.IN_CONTEXT)."""
    refs = case_references(case)
    return {"m_ref": refs["m_ref"], "k_ref": refs["k_ref"], "c_ref": refs["c_ref"],
            "rayleigh": bool(refs.get("rayleigh")),
            "channel_masses": is_fe(case.model) and not case.model.node_coords}


def log_conclusion(log, result, refs=None):
    """The printed conclusion: the verdict, each finding in physical units, the paragraph
    in plain words, the other statements, hypotheses, alternatives, suggestions, the fit
    (nlp.diagnosis.plain, as report.html says it)."""
    log(f"verdict: {result['verdict']}")
    for f in result["findings"]:
        log(f"  finding: {finding_title(f)}")
        for v in finding_values(f, refs):
            log(f"    {v}")
        if finding_note(f):
            log(f"    {finding_note(f)}")
    log(textwrap.fill("In plain words: " + paragraph(result, refs), 100, initial_indent="  ",
                      subsequent_indent="  "))
    for st in unconfirmed_lines(result, refs):
        log(f"  not confirmed: {st}")
    for st in other_statements(result):
        log("  " + st)
    for h in hypotheses(result):
        log(f"  hypothesis: {h}")
    for a in result.get("alternatives") or []:
        log(f"  alternative: {finding_line(a, refs)}")
    for sg in result.get("suggested_measurements", []):
        log(f"  suggested measurement: {sg}")
    b, a = result["fit"]["before"], result["fit"]["after"]
    log(f"  fit before: reduced chi-square {b['reduced_chi2']:.2f}, held-out "
        f"{b['held_out_chi2']:.2f}; after: {a['reduced_chi2']:.2f}, {a['held_out_chi2']:.2f}")


def write_conclusion(out, c):
    """Write a look's figures and out/diagnosis.json."""
    os.makedirs(out, exist_ok=True)
    plot_diagnosis(out, c.case, c.base, c.z_base, c.improved, c.z_improved, c.cells_before,
                   c.cells_after, c.family)
    write_json(os.path.join(out, "diagnosis.json"), c.result)
    # beside diagnosis.json (which it leaves as it was): report.html gives an appendage's
    # mass in kg from its mass ratio with these
    write_json(os.path.join(out, REFERENCES), physical_references(c.case))
