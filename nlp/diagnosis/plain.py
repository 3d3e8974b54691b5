"""The conclusion of a diagnosis in an engineer's words, from diagnosis.json.

The printed conclusion of ``frf-nlp diagnose`` (:mod:`nlp.diagnosis.verdict`) and
report.html (:mod:`nlp.output.report`) both come from here, so they say the same: each
finding with its parameters in physical units (:mod:`nlp.diagnosis.units`), one paragraph
saying what is missing, where, how big and how much the fit improved, and the effects the
updated parameters may have absorbed, worded as hypotheses.
"""

from nlp.diagnosis.level_kind import mechanism_words
from nlp.diagnosis.units import FAMILY_WORDS, describe, fmt_sig, place, quantities, quantity

__all__ = ["finding_title", "finding_values", "held_words", "finding_line", "paragraph",
           "hypotheses", "other_statements", "unconfirmed_lines", "finding_note", "REFERENCES", "REMAINING", "EXTRA_MODES", "REST_HEAD",
           "beyond_fit"]

REFERENCES = "references.json"   # beside diagnosis.json: the families' reference magnitudes
# statements of verdict.py that the paragraph says in its own words (not repeated)
REMAINING = ("With this added, residuals are still above the noise: more is missing than the "
             "candidate families describe.")
EXTRA_MODES = "Resonances the model does not have (extra modes): "
REST_HEAD = "The rest of the mismatch sits on "   # verdict.left_statement; shown as a table
REFIT_STATEMENT = "The data show "   # how a refitted finding's statement begins

# the parameter that says how big a finding is (else its first one)
SIZE = {"base_flexibility": ("log10_kb",), "secondary_oscillator": ("mu", "f_s"),
        "nonlinearity": ("relative_change",)}


def finding_title(f):
    """'a flexible base in the whole structure'."""
    mech = mechanism_words(f)
    words = mech[0] if mech else FAMILY_WORDS.get(f.get("physics"), f.get("physics", ""))
    return f"{words} {place(f.get('location'))}"


def finding_values(f, refs=None):
    """Each parameter of a finding in units with its relative error, then the parameters
    the data leave open."""
    mech = mechanism_words(f)
    vals = [mech[1]] if mech and mech[1] else []
    vals += [f"{q.label} {describe(q)}" for _, q in quantities(f, refs)]
    if f.get("not_determined"):
        vals.append("not determined by the data: " + ", ".join(
            f"{quantity(f.get('physics'), n, 0.0).label} ({n})" for n in f["not_determined"]))
    vals += held_words(f.get("physics"), f.get("held") or {}, labels=True,
                       stated=f.get("held_reference"))
    return vals


def held_words(physics, held, labels=False, stated=None):
    """'zeta_s4 held at 2 % (assumed: the data do not determine it)' for each parameter a
    finding holds at its reference value (nlp.diagnosis.nuisance): an assumption, never an
    estimate, so no error is given. stated: {name: reference} of those held not at their
    stated reference, which the data exclude, but at the nearest value the data allow."""
    out = []
    for n, v in held.items():
        q = quantity(physics, n, float(v))
        head = f"{q.label} {q.symbol}" if labels else n
        unit = " " + q.unit if q.unit else ""
        why = "(assumed: the data do not determine it)"
        if n in (stated or {}):
            ref = quantity(physics, n, float(stated[n]))
            why = (f"(the data do not determine it, but exclude its reference "
                   f"{fmt_sig(ref.value)}{unit}: the nearest value they allow)")
        out.append(f"{head} held at {fmt_sig(q.value)}{unit} {why}")
    return out


def finding_note(f):
    """The finding's own statement when it says more than its values (how an effect inside
    the model class, a phase delay or a level dependence was found); None for a refit's
    statement, which only repeats the values as fitted (verdict.statement: REFIT_STATEMENT)."""
    st = f.get("statement")
    return None if not st or st.startswith(REFIT_STATEMENT) else st


def finding_line(f, refs=None):
    """One line: what, where, and its values."""
    return f"{finding_title(f)}: " + "; ".join(finding_values(f, refs))


def _size(f, refs):
    """The quantities that say how big a finding is, with their errors."""
    mech = mechanism_words(f)
    if mech and mech[1]:
        return mech[1]
    qs = quantities(f, refs)
    heads = SIZE.get(f.get("physics"))
    picked = [q for n, q in qs if heads and n.startswith(heads)] or [q for _, q in qs[:1]]
    return ", ".join(describe(q) for q in picked)


def _fit_words(fit):
    """How much the fit improved: reduced chi-square before -> after, held-out too."""
    b, a = fit.get("before") or {}, fit.get("after") or {}
    if not b:
        return ""
    sd = b.get("reduced_chi2_sd")
    noise = f" (a right noise model gives 1 ± {sd:.2f} here)" if sd else " (1 is the noise level)"
    if "other_level_held_out_chi2" in a and a.get("reduced_chi2") == b.get("reduced_chi2"):
        return (f"Across excitation levels, the other level's held-out misfit falls from "
                f"{fmt_sig(b['other_level_held_out_chi2'])} with one linear model to "
                f"{fmt_sig(a['other_level_held_out_chi2'])} with a model for each level.")
    return (f"The reduced chi-square of the fitted points goes from {fmt_sig(b['reduced_chi2'])} "
            f"to {fmt_sig(a['reduced_chi2'])}{noise}, and that of the held-out points (near "
            f"the windows, not fitted) from {fmt_sig(b['held_out_chi2'])} to "
            f"{fmt_sig(a['held_out_chi2'])}.")


def paragraph(d, refs=None):
    """What is missing, where, how big, and how much the fit improved (diagnosis.json d)."""
    verdict, found, fit = d.get("verdict"), d.get("findings") or [], d.get("fit") or {}
    b = fit.get("before") or {}
    if verdict == "setup_error" and not found:
        return ("The data contradict the case's set-up (see below); no physics is blamed "
                "until the case or the data are corrected.")
    if verdict == "setup_error":
        what = [f"{finding_title(f)}, {_size(f, refs)}" for f in found]
        return ("The structural model is adequate; the test set-up is not as the case file "
                "says: " + "; and ".join(what) + ". With " + ("this" if len(found) == 1 else
                                                              "these") + " corrected, "
                + _lower(_fit_words(fit)) + " Correct each channel's calibration or timing in "
                "the case, not the model.")
    if verdict == "adequate":
        sd = b.get("reduced_chi2_sd")
        return (f"Nothing is missing that the candidate families describe: the updated model "
                f"fits the measured FRFs within their noise (reduced chi-square "
                f"{fmt_sig(b.get('reduced_chi2'))}"
                + (f", where a right noise model gives 1 ± {sd:.2f}" if sd else "")
                + f"; held-out points {fmt_sig(b.get('held_out_chi2'))}).")
    parts = []
    if found:
        what = [f"{finding_title(f)}, {_size(f, refs)}" for f in found]
        # a story stiffer one way (nlp.diagnosis.asymmetry) is no term of the linear model
        added = [f for f in found if (f.get("mechanism") or {}).get("kind") != "asymmetric"]
        parts.append("The model leaves out " + "; and ".join(what) + ". " + (
            ("With it added, " if len(added) == 1 else "With these added, ")
            + _lower(_fit_words(fit)) if added else
            "No linear model can take it up, so the linear fit stays as it was (reduced "
            f"chi-square {fmt_sig(b.get('reduced_chi2'))}, held-out "
            f"{fmt_sig(b.get('held_out_chi2'))})."))
    else:
        parts.append("The model does not explain the data, and the data cannot tell which "
                     "physics is missing" + (": " + _join([finding_title(f) for f in
                                                           d.get("indistinguishable") or
                                                           d.get("unconfirmed") or []])
                                             if d.get("indistinguishable") or d.get("unconfirmed")
                                             else "") + ". " + _fit_words(fit))
    if d.get("remaining_mismatch"):
        parts.append("The fit is still worse than the noise allows: more is missing than "
                     "the candidate families describe, so the diagnosis explains the data "
                     "only in part" + _left_words(d.get("mismatch_left")) + ".")
    disc = d.get("model_discrepancy") or []
    if disc:
        parts.append(_discrepancy_words(disc))
    parts.append(_alone_words(d.get("tests_alone") or []))
    parts.append(_spread_words(d.get("between_tests") or [], refs))
    extra = d.get("extra_modes") or []
    if extra:
        parts.append("The data also show resonances the model does not have, at "
                     + _join([f"{e['frequency_hz']:.2f} Hz" for e in extra]) + ".")
    if verdict == "ambiguous" and d.get("suggested_measurements"):
        parts.append("The suggested measurements below would tell the candidates apart.")
    return " ".join(p for p in parts if p)


def _discrepancy_words(disc):
    """The resonances the model class cannot have: fitted in the band, reported beyond it."""
    def at(xs):
        return _join([f"{x['frequency_hz']:.2f} Hz (seen by {_join(x['channels'])})"
                      if x.get("channels") else f"{x['frequency_hz']:.2f} Hz" for x in xs])
    fitted = [x for x in disc if x.get("fitted") is not False]
    beyond = [x for x in disc if x.get("fitted") is False]
    text = ("The data show " + ("a resonance" if len(disc) == 1 else "resonances")
            + " that the model class cannot have, at " + at(disc)
            + ": likely out-of-plane, torsional or local modes.")
    hz = _join([f"{x['frequency_hz']:.2f}" for x in beyond]) + " Hz" if beyond else ""
    if fitted:
        text += (" Inside the fitted band " + (f"({_join([format(x['frequency_hz'], '.2f') for x in fitted])} Hz) "
                                              if beyond else "")
                 + ("it is" if len(fitted) == 1 else "they are") + " kept in the fit as model "
                 "discrepancy, so no finding above is accepted for absorbing "
                 + ("it" if len(fitted) == 1 else "them") + ".")
    if beyond:
        text += (f" {'The one at ' if len(beyond) == 1 else ''}{hz} "
                 + ("lies" if len(beyond) == 1 else "lie") + " beyond the fitted band and "
                 + ("is" if len(beyond) == 1 else "are") + " not fitted.")
    return text


def _alone_words(alone):
    """How the tests, each fitted alone, bear out the joint findings (nlp.diagnosis.joint)."""
    if not alone:
        return ""
    tests = list(dict.fromkeys(r["test"] for r in alone))
    bad = [r for r in alone if not r["agrees"]]
    head = f"The findings come from the {len(tests)} tests fitted jointly ({_join(tests)})"
    if not bad:
        return head + "; each test fitted alone agrees with every one of them."
    return head + "; fitted alone, " + "; ".join(
        f"{r['test']} {'cannot see' if 'cannot' in r['reason'] else 'disagrees on'} "
        f"{finding_title(r)}" for r in bad) + " (see the table of each test alone)."


def _spread_words(spread, refs=None):
    """The joint values the tests, fitted alone, spread around by more than their errors
    (nlp.diagnosis.joint.between_tests), with the errors that spread gives them."""
    wide = [s for s in spread if s["wider"]]
    if not wide:
        return ""
    vals = ["; ".join(finding_values({"physics": s["physics"],
                                      "parameters": {s["parameter"]: s["joint"]},
                                      "uncertainty": {s["parameter"]: s["standard_error"]}}, refs))
            + f" for {finding_title(s)}" for s in wide]
    return ("Fitted alone, the tests differ from each other by more than the joint fit's "
            "errors allow (those hold for noise about one right model); with that spread "
            "counted (random effects, DerSimonian and Laird 1986) the joint "
            + ("value is" if len(wide) == 1 else "values are") + " known only to: "
            + "; ".join(vals) + ".")


def alone_rows(d, refs=None):
    """Rows (test, finding, its value alone, its value jointly, what the test says) of the
    joint findings on each test alone."""
    rows = []
    for r in d.get("tests_alone") or []:
        alone = {"physics": r["physics"], "parameters": r["alone"],
                 "uncertainty": r["alone_uncertainty"]}
        joint = {"physics": r["physics"], "parameters": r["joint"],
                 "uncertainty": r["joint_uncertainty"]}
        rows.append([r["test"], finding_title(r), "; ".join(finding_values(alone, refs)),
                     "; ".join(finding_values(joint, refs)),
                     "agrees" if r["agrees"] else r["reason"]])
    return rows


def beyond_fit(cell, span):
    """Does a channel x band cell of the whole-band map lie outside the fitted band?"""
    lo, hi = cell["band_hz"]
    return bool(span) and (lo >= span[1] * (1 - 1e-9) or hi <= span[0] * (1 + 1e-9))


def _left_words(left):
    """Where the rest sits, in a few words: the worst channels and bands."""
    cells = (left or {}).get("cells") or []
    span = (left or {}).get("fitted_band_hz")
    inside = [c for c in cells if not beyond_fit(c, span)][:3]
    outside = [c for c in cells if beyond_fit(c, span)][:2]

    def words(cs):
        return _join([f"{c['channel']} at {c['band_hz'][0]:.0f}-{c['band_hz'][1]:.0f} Hz"
                      for c in cs])

    text = f"; the rest sits mostly on {words(inside)}" if inside else ""
    if outside:
        text += (", and beyond the fitted band on " if inside
                 else "; the rest sits beyond the fitted band, mostly on ") + words(outside)
    return text


def _join(items):
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _lower(text):
    return text[:1].lower() + text[1:]


def hypotheses(d):
    """The absorbed effects the fitted parameters point at, as hypotheses (entries without
    such a pointer, written by older versions, are left out: they show nothing)."""
    params = {p["parameter"]: p for p in d.get("fitted_parameters") or []}
    out = []
    for a in d.get("absorbed") or []:
        if not a.get("indicator"):
            continue
        loc = a.get("location") or {}
        p = params.get(f"m{loc.get('floor')}") if a.get("physics") == "added_mass" else None
        if p and p.get("standard_error"):
            z = p["relative_change"] / p["standard_error"]
            prior = (f", {p['z_prior']:.1f} prior sigmas" if p.get("z_prior") is not None else "")
            seen = (f"the fitted mass of floor {loc['floor']} rose "
                    f"{100 * p['relative_change']:.0f} % ({z:.0f} standard errors{prior})")
        else:
            seen = a["indicator"]
        out.append(f"{_upper(seen)}: {FAMILY_WORDS.get(a['physics'], a['physics'])} "
                   f"{place(loc)} would look like this, and the updated parameters can take it "
                   "up (a hypothesis, not a finding).")
    return out


def _upper(text):
    return text[:1].upper() + text[1:]


def other_statements(d):
    """The summary's statements that the paragraph and unconfirmed_lines do not say in
    their own words: ties, parameter changes, level dependence, ..."""
    own = {f.get("statement") for f in d.get("findings") or []} | {REMAINING}
    heads = tuple(u["statement"][:-1] for u in d.get("unconfirmed") or [] if u.get("statement"))
    heads += (EXTRA_MODES, REST_HEAD)
    own |= {x.get("statement") for x in d.get("model_discrepancy") or []}
    return [s for s in d.get("summary") or [] if s not in own and not (heads and s.startswith(heads))]


def unconfirmed_lines(d, refs=None):
    """Candidates that did not hold on another test of the structure, with their values
    here and there in units and the reason."""
    out = []
    for c in d.get("consistency") or []:
        if c.get("holds", True):
            continue
        here = {"physics": c["physics"], "parameters": c.get("here") or {},
                "uncertainty": c.get("here_uncertainty") or {}}
        there = {"physics": c["physics"], "parameters": c.get("there") or {},
                 "uncertainty": c.get("there_uncertainty") or {}}
        out.append(f"{finding_title(c)}: " + "; ".join(finding_values(here, refs))
                   + f"; on {c['test']}: " + "; ".join(finding_values(there, refs))
                   + f". It does not hold there ({c.get('reason', '')}): not accepted.")
    return out
