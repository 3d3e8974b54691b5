"""Several tests of one structure diagnosed jointly (data.tests), then each test alone.

The joint fit (:mod:`nlp.case.joint`) shares the structure and the sensors between the
tests, so a finding is one set of values for the structure, and a sensor gain is one
number for a sensor wherever it was used. Each test alone is then refitted with the
joint findings and the part of the model discrepancy its channels see, from the joint
optimum. For each finding it either agrees with the joint estimate (its own evidence
passes and the two estimates lie within AGREE combined standard errors), or the record
says why not: the test cannot see it (its effect is within SIGNIFICANCE standard errors
of zero there, or its BIC change there is too small), or the test disagrees (the finding
is test-specific there).
"""

from dataclasses import replace

import numpy as np

from nlp.case.assemble import assemble, single_tests
from nlp.case.joint import JOINT_SEP
from nlp.diagnosis.evidence import (BIC_ACCEPT, agree, dispersion, effect_terms, random_effects,
                                    scaled_delta_bic, significance)
from nlp.diagnosis.families import ExtraMode
from nlp.diagnosis.fitting import best_fit, diagnosis_problem, fit_target, noise_sigma, quasi_se
from nlp.diagnosis.reciprocity import gain_contradiction, reciprocal_pairs

__all__ = ["alone_fits", "own_modes", "start_by_name", "reciprocity_of_tests", "between_tests",
           "WIDER"]

WIDER = 2.0   # a spread is reported when it widens a joint error by this factor or more


def own_modes(discrepancy, label, first):
    """The model-discrepancy terms restricted to one test's channels, named as that test
    alone names them (the first test's channels carry no label)."""
    out = []
    for m in discrepancy:
        keep = [k for k, c in enumerate(m.channels)
                if (JOINT_SEP not in c if first else c.endswith(JOINT_SEP + label))]
        if keep:
            out.append(ExtraMode(m.f0, tuple(m.channels[k].split(JOINT_SEP)[0] for k in keep),
                                 tuple(m.powers[k] for k in keep),
                                 tuple(m.levels[k] for k in keep)))
    return out


def start_by_name(pr, values):
    """Decision vector of pr with theta taken by parameter name from values (clipped to
    the bounds; others at their initial value)."""
    theta = pr.theta(pr.z0).copy()
    for i, p in enumerate(pr.params.params):
        if p.name in values and not p.fixed:
            theta[i] = min(max(values[p.name], p.lower), p.upper)
    return pr.params.z_from_theta(theta)


def _on_grid(c, fit_f):
    """Indices of the frequencies fit_f [Hz] on the grid of case c (those it holds)."""
    k = np.clip(np.searchsorted(c.f, fit_f), 0, c.f.size - 1)
    return np.unique(k[np.isclose(c.f[k], fit_f, rtol=1e-9, atol=0.0)])


def reciprocity_of_tests(cfg, fit_f):
    """The model-free gain ratios of the sensors (:func:`reciprocal_pairs`) between the first
    test and each other test, on the joint look's fitted frequencies fit_f [Hz]. The ratios
    name sensors, as the gains of the joint fit do."""
    singles = [(label, assemble(c, data_file=path)) for label, c, path in single_tests(cfg)]
    first = singles[0][1]
    others = [{"label": label, "case": c, "idx": _on_grid(c, fit_f)} for label, c in singles[1:]]
    return reciprocal_pairs(first, others, _on_grid(first, fit_f))


def _joint_values(pr, z, label, first):
    """Joint theta by the name a test alone gives each parameter."""
    out = {}
    for n, v in zip(pr.params.names, pr.theta(z)):
        if JOINT_SEP in n:
            if not first and n.endswith(JOINT_SEP + label):
                out[n.split(JOINT_SEP)[0]] = float(v)
        elif first or not n.startswith("a_x"):
            out.setdefault(n, float(v))
    return out


def alone_fits(cfg, case, fit_f, found, state, log, pairs=()):
    """[record] of each finding on each test alone (module docstring): test, physics,
    location, the joint estimate ("joint", "joint_uncertainty") and the test's ("alone",
    "alone_uncertainty"), delta_bic_alone, agrees and reason. fit_f: the fitted
    frequencies [Hz] of the joint look; pairs: the tests' reciprocal gain ratios
    (:func:`reciprocity_of_tests`), which say why a test alone misplaces a gain."""
    if not found:
        return []
    pr_j, z_j = state["problem"], state["z"]
    records = []
    for t, (label, c_cfg, path) in enumerate(single_tests(cfg)):
        c_t = assemble(c_cfg, data_file=path)
        c_t = replace(c_t, discrepancy=tuple(own_modes(case.discrepancy, label, t == 0)))
        idx = _on_grid(c_t, fit_f)
        target = fit_target(c_t, idx, noise_sigma(c_t, idx))
        values = _joint_values(pr_j, z_j, label, t == 0)
        enr = [r["enrichment"] for r in found]
        pr = diagnosis_problem(c_t, target, enr, optimize=False)
        res = best_fit(pr, [start_by_name(pr, values), pr.z0])
        th, se = pr.theta(res.z), quasi_se(pr, res.z)[0]
        chi = 2 * res.f
        phi = dispersion(chi, pr.n_used - pr.params.n_z)
        gains = {r["location"]["channel"]: (float(th[i]), float(se[i])) for r in found
                 if r["physics"] == "sensor_gain"
                 for i in [pr.params.names.index(next(iter(r["parameters"])))]}
        contra = gain_contradiction(pairs, {c: g for c, (g, _) in gains.items()},
                                    {c: s for c, (_, s) in gains.items()}) if gains else ""
        for j, r in enumerate(found):
            rec = _record(c_t, target, enr, j, r, pr, th, se, chi, phi, values, label)
            if rec["physics"] == "sensor_gain" and not rec["agrees"] and contra:
                # the test alone has no reciprocal FRF to fix the gain ratio: its gain takes up
                # model error, as the model-free ratio shows
                rec["reason"] = ("this test alone cannot fix the gain: " + contra.split(
                    "reciprocity: ", 1)[-1])
            records.append(rec)
            log(_line(records[-1]))
    return records


def _record(c_t, target, enr, j, r, pr, th, se, chi, phi, values, label):
    """One finding on one test alone."""
    names = list(r["parameters"])
    ix = [pr.params.names.index(n) for n in names]
    v2, s2 = [float(th[i]) for i in ix], [float(se[i]) for i in ix]
    v1 = [r["parameters"][n] for n in names]
    s1 = [r["uncertainty"][n] for n in names]
    pr0 = diagnosis_problem(c_t, target, enr[:j] + enr[j + 1:], optimize=False)
    chi0 = 2 * best_fit(pr0, [start_by_name(pr0, values), pr0.z0]).f
    d = scaled_delta_bic(chi, chi0, len(names), pr.n_used, phi)
    sig_ok, why = significance(r["physics"], names, v2, s2, lr=(chi0 - chi) / phi)
    same = all(agree(a[1], a[2], b[1], b[2]) for a, b in
               zip(effect_terms(r["physics"], names, v1, s1),
                   effect_terms(r["physics"], names, v2, s2)))
    if not sig_ok or d > -BIC_ACCEPT:
        reason = "this test cannot see it: " + (why if not sig_ok else
                                                f"its BIC change here is only {d:.1f}")
        agrees = False
    elif not same:
        reason = ("test-specific: the estimate here and the joint one differ by more than "
                  "3 combined standard errors")
        agrees = False
    else:
        reason, agrees = "", True
    return {"test": label, "physics": r["physics"], "location": r["location"],
            "joint": dict(zip(names, v1)), "joint_uncertainty": dict(zip(names, s1)),
            "alone": dict(zip(names, v2)), "alone_uncertainty": dict(zip(names, s2)),
            "delta_bic_alone": float(d), "agrees": bool(agrees), "reason": reason}


def between_tests(records):
    """How far the tests, each fitted alone, spread around every joint finding's values.

    The joint fit's quasi-likelihood errors hold for noise around one right model; when
    each test's own model error pulls its estimate elsewhere, the tests disagree by more
    than those errors, and the spread between them is the honest measure of how well the
    value is known. Per parameter, over the tests that see the finding (at least two): the
    between-test spread tau and the random-effects standard error of a value common to the
    tests (:func:`nlp.diagnosis.evidence.random_effects`).

    Returns [{physics, location, parameter, tests, values, tau, standard_error, joint,
    joint_uncertainty, wider}]; wider: the random-effects error is WIDER times the joint
    one or more.
    """
    groups = {}
    for r in records:
        if r["reason"].startswith("this test cannot see it"):
            continue
        for n, v in r["alone"].items():
            se = r["alone_uncertainty"][n]
            if np.isfinite(v) and np.isfinite(se) and se > 0:
                groups.setdefault((r["physics"], repr(r["location"]), n), []).append((r, v, se))
    out = []
    for (_, _, name), rows in groups.items():
        if len(rows) < 2:
            continue
        y = [v for _, v, _ in rows]
        tau, se_re = random_effects(y, [se for _, _, se in rows])
        r0 = rows[0][0]
        joint_se = r0["joint_uncertainty"][name]
        out.append({"physics": r0["physics"], "location": r0["location"], "parameter": name,
                    "tests": [r["test"] for r, _, _ in rows], "values": y,
                    "tau": tau, "standard_error": se_re,
                    "joint": r0["joint"][name], "joint_uncertainty": joint_se,
                    "wider": bool(se_re >= WIDER * joint_se)})
    return out


def _line(rec):
    vals = ", ".join(f"{n} {a:.4g}+-{b:.2g}" for (n, a), b in
                     zip(rec["alone"].items(), rec["alone_uncertainty"].values()))
    return (f"  {rec['physics']} {rec['location']} on {rec['test']} alone: dBIC "
            f"{rec['delta_bic_alone']:.1f}, {vals} "
            + ("(agrees with the joint fit)" if rec["agrees"] else f"({rec['reason']})"))
