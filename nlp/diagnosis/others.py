"""The case's other tests of the same structure (validation file, other levels).

A candidate found on the case's data is kept only when it holds on every other test
(hold_on_others); candidates the other tests rank high are refitted here too
(refits_of_others), so two tests do not take different paths.
"""

from dataclasses import replace
import os

from nlp.case.assemble import assemble
from nlp.case.schema import ExcitationConfig
from nlp.errors import InputError
from nlp.diagnosis.candidates import candidates, same, score, to_refit
from nlp.diagnosis.evidence import (BIC_ACCEPT, agree, dispersion, effect_terms, evidence,
                                    identity_terms, scaled_delta_bic, significance)
from nlp.diagnosis.fitting import (best_fit, diagnosis_problem, fit_target, fit_windows,
                                   noise_sigma, quasi_se, with_values)


def other_tests(cfg):
    """(label, config, data file) of the case's other tests of the same structure."""
    d = cfg.data
    out = []
    if d.validation_file:
        vcfg = cfg
        if d.validation_force_floor is not None:
            vcfg = replace(cfg, excitation=ExcitationConfig("force", d.validation_force_floor))
        out.append((os.path.basename(d.validation_file), vcfg, d.validation_file))
    for p in d.level_files:
        out.append((os.path.basename(p), cfg, p))
    return out


def assemble_other(c_cfg, path, log=print):
    """(case, None) of another test of the structure, or (None, the reason) when its data
    allow no fit: they fail a check of their own (a response not coherent with the input,
    no resonance above their noise for the frequency selection). Such a test can neither
    confirm nor refute a finding, and must not stop the diagnosis of the case's own data,
    which passed the same checks; the reason is logged. An error in the case file itself
    is raised."""
    try:
        return assemble(c_cfg, data_file=path), None
    except InputError as exc:
        if exc.file != str(path) and not exc.key.startswith("frequencies"):
            raise
        why = f"'{exc.key}' expected {exc.expected}" + \
            (f", got {exc.got!r}" if exc.got is not None else "")
        log(f"  other test {os.path.basename(str(path))} not used: {why}")
        return None, why


def setup_others(cfg, discrepancy=(), log=print):
    """Each other test of the structure, assembled once: case, fitted points, target; the
    model discrepancy of this test (its modes belong to the structure) is kept there.
    Tests whose data allow no fit are left out (:func:`assemble_other`)."""
    out = []
    for label, c_cfg, path in other_tests(cfg):
        c2, _ = assemble_other(c_cfg, path, log)
        if c2 is None:
            continue
        c2 = replace(c2, discrepancy=tuple(discrepancy))
        idx = fit_windows(c_cfg, c2, 1)
        out.append({"label": label, "case": c2, "target": fit_target(c2, idx, noise_sigma(c2, idx)),
                    "at": {}, "idx": idx})
    return out


def other_optimum(o, current, z_here):
    """The current model fitted on another test, cached per model: (z, chi-square).

    Started from this test's optimum and the nominal point; once a finding is
    adopted its optimum there comes from :func:`hold_on_others`."""
    key = tuple(repr(e) for e in current)
    if key not in o["at"]:
        pr = diagnosis_problem(o["case"], o["target"], current, optimize=False)
        res = best_fit(pr, [z_here, pr.z0])
        o["at"][key] = (res.z, 2 * res.f)
    return o["at"][key]


def refits_of_others(others, state, jobs, scores_here, top):
    """Add to this round's refits the candidates the other tests rank high.

    The score test is a first-order look at one test; a finding that ranks low
    here but high on another test of the structure would otherwise never be
    refitted here, and two tests would take different paths (a sensor gain ranked
    9th by score on one test of a real structure, yet its BIC drop there was larger
    than that of the finding chosen)."""
    have = {repr(e) for _, e in jobs}
    for o in others:
        z_o, _ = other_optimum(o, state["current"], state["z"])
        scored = sorted(((score(o["case"], o["target"], state["current"], z_o, e)[0], e)
                         for e in candidates(o["case"]) if not same(e, state["current"])),
                        key=lambda t: -t[0])
        for _, e in to_refit(scored, top):
            if repr(e) not in have and repr(e) in scores_here:
                jobs.append((scores_here[repr(e)], e))
                have.add(repr(e))
    return jobs


def hold_on_others(others, state, accepted, log):
    """Keep the accepted candidates that hold on every other test of the structure.

    On each other test, the current model with and without the candidate is
    fitted (starting from this test's optimum and from that test's own). The
    candidate holds there when it is accepted on its own evidence (scaled BIC
    drop >= BIC_ACCEPT, effect > 3 standard errors, no error above its value)
    and its effect, and what it is (an appendage's frequency: evidence.identity_terms), agree
    with this test's within 3 combined standard errors.
    Sets r["delta_bic_others"] (the sum of the scaled BIC changes there, which
    :func:`evidence` adds, so every test of the structure weighs in the ranking)
    and r["there"] (its optimum on each test). Returns (kept, rejected, records).
    """
    refs = {o["label"]: other_optimum(o, state["current"], state["z"]) for o in others}
    kept, rejected, records = [], [], []
    for r in accepted:
        names = list(r["parameters"])
        v1 = [r["parameters"][n] for n in names]
        s1 = [r["uncertainty"][n] for n in names]
        holds_all, d_sum, there = True, 0.0, {}
        for o in others:
            z_o, chi_o = refs[o["label"]]
            pr2 = diagnosis_problem(o["case"], o["target"], state["current"] + [r["enrichment"]],
                           optimize=False)
            res = best_fit(pr2, [r["z"], with_values(pr2, z_o, v1), pr2.z0])
            th2, se2 = pr2.theta(res.z), quasi_se(pr2, res.z)[0]
            ix = [pr2.params.names.index(n) for n in names]
            v2, s2 = [float(th2[i]) for i in ix], [float(se2[i]) for i in ix]
            chi2 = 2 * res.f
            phi2 = dispersion(chi2, pr2.n_used - pr2.params.n_z)
            d2 = scaled_delta_bic(chi2, chi_o, len(names), pr2.n_used, phi2)
            d_sum += d2
            there[o["label"]] = (res.z, chi2)
            sig_ok, why = significance(r["physics"], names, v2, s2, lr=(chi_o - chi2) / phi2)
            same = all(agree(a[1], a[2], b[1], b[2]) for a, b in
                       zip(effect_terms(r["physics"], names, v1, s1)
                           + identity_terms(r["physics"], names, v1, s1),
                           effect_terms(r["physics"], names, v2, s2)
                           + identity_terms(r["physics"], names, v2, s2)))
            holds = bool(d2 <= -BIC_ACCEPT and sig_ok and same)
            reason = ("" if holds else
                      f"its BIC change there is only {d2:.1f}" if d2 > -BIC_ACCEPT else
                      why if not sig_ok else
                      "the two estimates differ by more than 3 combined standard errors")
            records.append({"test": o["label"], "physics": r["physics"], "location": r["location"],
                            "here": dict(zip(names, v1)), "here_uncertainty": dict(zip(names, s1)),
                            "there": dict(zip(names, v2)), "there_uncertainty": dict(zip(names, s2)),
                            "delta_bic_there": d2, "holds": holds, "reason": reason})
            log(f"    {r['physics']} {r['location']} on {o['label']}: dBIC {d2:.1f}, "
                + ", ".join(f"{n} {a:.4g}+-{b:.2g}" for n, a, b in zip(names, v2, s2))
                + (" (holds)" if holds else f" (does not hold: {reason})"))
            holds_all &= holds
        r["delta_bic_others"], r["there"] = d_sum, there
        r["records"] = records[-len(others):]
        if holds_all:
            kept.append(r)
        else:
            r["accepted"] = False
            r["why_not"] = "does not hold on another test of the structure"
            rejected.append(r)
    return sorted(kept, key=evidence), rejected, records


def final_records(sel):
    """The other tests' records of the final findings and of what failed there, and each
    unconfirmed candidate once, from its last test (made on top of the final findings)."""
    final = {(r["physics"], repr(r["location"])) for r in sel.found}
    last = {(c["test"], c["physics"], repr(c["location"])): c for c in sel.consistency}
    consistency = [c for c in last.values()   # one record per test and candidate, the last
                   if (c["physics"], repr(c["location"])) in final or not c["holds"]]
    seen = set(final)
    unconfirmed = [r for r in reversed(sel.unconfirmed)
                   if (r["physics"], repr(r["location"])) not in seen
                   and not seen.add((r["physics"], repr(r["location"])))][::-1]
    return consistency, unconfirmed
