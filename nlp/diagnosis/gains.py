"""Gains beyond the calibration tolerance: the stage that frees them, one sensor at a time.

After the baseline, with every channel's gain inside the case's tolerance
(:mod:`.calibration`), a gain on its bound is what the data would have beyond it. Each such
sensor's gain is freed in turn from the current optimum; the one with the largest scaled
BIC drop that passes :func:`nlp.diagnosis.calibration.release_check` is named, and the
search repeats from that fit (forward selection, as the rounds do) until none passes. The
named gains stay free in every later fit, so the structural rounds are judged with them.

Freed before the rounds, a gain can take up a structural effect's misfit: an added mass
that lowers one floor's response reads, to a model without it, as that channel reading low.
So each named gain is judged again in the final model (:func:`confirmed_gains`): bounded
once more, with the structural findings in; it is kept only if the same rules still hold,
and its value and error are the final fit's.
"""

from dataclasses import replace

import numpy as np

from nlp.diagnosis.calibration import calibration_of, gains_at_bound, release_check
from nlp.diagnosis.checkpoint import fingerprint, logged_step
from nlp.diagnosis.fitting import best_fit, diagnosis_problem, normalised, quasi_se

__all__ = ["calibration_stage", "released_gains", "confirmed_gains", "reference_of",
           "gain_finding", "calibration_summary"]


def calibration_stage(case, points, base, log, refit):
    """(case, points, baseline) with the gains the data put beyond the case's calibration
    tolerance freed and the baseline refitted by refit(case, points, z); unchanged when the
    case states no tolerance or no gain is beyond it."""
    if not case.config.data.calibration:
        return case, points, base
    found, z = logged_step("calibration", fingerprint(points.fit, base.res.z), lambda lg:
                           released_gains(case, points, base.res.z, base.chi, base.held,
                                          base.nu, base.n_fit, lg), log)
    if not found:
        return case, points, base
    case = replace(case, released_gains=tuple(found))
    points = replace(points, base=diagnosis_problem(case, points.target))
    return case, points, replace(refit(case, points, z), before=base)


def _fit(case, target, z, points, current=()):
    """(chi2, theta, se, names, held-out, z, problem) of the case's model (with the
    enrichments current) solved from z."""
    pr = diagnosis_problem(case, target, list(current), optimize=False)
    res = best_fit(pr, [z])
    held = float(np.mean(normalised(pr, res.z, case, points.held, points.sig_held) ** 2))
    return (2 * res.f, pr.theta(res.z), quasi_se(pr, res.z)[0], list(pr.params.names), held,
            res.z, pr)


def released_gains(case, points, z, chi, held, nu, n_fit, log):
    """(released gain findings, z at the last accepted fit): the gains the data put beyond
    the tolerance, from the baseline optimum z (chi-square chi, held-out held)."""
    found = []
    cur = (chi, points.base.theta(z), None, list(points.base.params.names), held, z, None)
    while True:
        c = replace(case, released_gains=tuple(found))
        cal = calibration_of(c)
        at = gains_at_bound(cal, cur[3], cur[1])
        trials = []
        for s in at:
            c1 = replace(case, released_gains=tuple(found) + (gain_finding(s, 0.0, 0.0, {}),))
            f1 = _fit(c1, points.target, cur[5], points)
            ev = release_check(cal, s, cur[:4], f1[:4], n_fit, nu - len(found), cur[4], f1[4])
            log(f"  calibration: gain of {s} freed beyond the tolerance: {100 * ev['gain']:+.1f} "
                f"+- {100 * ev['se']:.1f} %, dBIC {ev['delta_bic']:.1f}, held-out "
                f"{f1[4]:.2f} (was {cur[4]:.2f}){' (named)' if ev['accepted'] else ''}")
            if ev["accepted"]:
                trials.append((ev["delta_bic"], s, ev, f1))
        if not trials:
            return found, cur[5]
        _, s, ev, cur = min(trials, key=lambda t: t[0])
        found.append(gain_finding(s, ev["gain"], ev["se"], ev, cal.tolerance, reference_of(case)))
        log(f"calibration: the gain of {s} is named beyond the tolerance (judged again in "
            "the final model)")


def confirmed_gains(case, points, state, nu, n_fit, log):
    """(case, state): the released gains that still pass release_check in the final model
    (state: its enrichments, z, chi-square, held-out and problem); the others bounded again
    and the final model refitted without them."""
    kept = list(case.released_gains)
    for f in list(kept):
        s = f["location"]["channel"]
        c0 = replace(case, released_gains=tuple(g for g in kept if g is not f))
        f0 = _fit(c0, points.target, state["z"], points, state["current"])
        pr = state["problem"]
        theta, se = pr.theta(state["z"]), quasi_se(pr, state["z"])[0]
        f1 = (state["chi"], theta, se, list(pr.params.names))
        cal = calibration_of(c0)
        ev = release_check(cal, s, f0[:4], f1, n_fit, nu, f0[4], state["held"])
        if ev["accepted"]:   # the final fit's value, error and evidence
            kept[kept.index(f)] = gain_finding(s, ev["gain"], ev["se"], ev, cal.tolerance,
                                               reference_of(case))
            continue
        log(f"calibration: the gain of {s} is within the tolerance in the final model "
            f"({100 * ev['gain']:+.1f} +- {100 * ev['se']:.1f} %, dBIC {ev['delta_bic']:.1f} "
            "for freeing it): not named")
        kept.remove(f)
        state = {"current": state["current"], "z": f0[5], "chi": f0[0], "held": f0[4],
                 "problem": f0[6]}
    return replace(case, released_gains=tuple(kept)), state


def reference_of(case):
    """The channel a force test's gains are relative to (held at 0: the structure's scale
    carries a gain common to every channel), or None (relative to the input)."""
    cal = calibration_of(case)
    first = case.channels[0].sensor_name
    return None if cal is None or first in cal.channels else first


def gain_finding(sensor, g, se, evidence, tolerance=0.0, reference=None):
    """A sensor_gain finding: the channel's gain beyond the stated calibration tolerance."""
    name = f"gain_{sensor}"
    versus = f"channel {reference}" if reference else "the input"
    return {"physics": "sensor_gain", "location": {"channel": sensor},
            "parameters": {name: float(g)}, "uncertainty": {name: float(se)},
            "evidence": {"source": "calibration", **{k: v for k, v in evidence.items()
                                                     if k in ("delta_bic", "beyond_se", "phi")}},
            "statement": (f"Channel {sensor} reads {100 * abs(g):.1f} +- {100 * se:.1f} % "
                          f"{'high' if g > 0 else 'low'} relative to {versus}, beyond the "
                          f"+-{100 * tolerance:.0f} % the transducers' calibration allows: "
                          "check this sensor's calibration and its conditioner's gain.")}


def calibration_summary(case, problem, z):
    """{sensor: gain} of the final fit, and the tolerance's bounds, for the report."""
    cal = calibration_of(case)
    if cal is None:
        return None
    theta, names = problem.theta(z), list(problem.params.names)
    gains = {s: float(theta[names.index(f"cal_{s}")]) for s in cal.channels}
    return {"tolerance": cal.tolerance, "bounds": list(cal.bounds), "gains": gains,
            "reference": reference_of(case), "released": list(cal.released)}
