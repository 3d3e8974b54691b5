"""What changes with the excitation level: a story's stiffness, a floor's mass or a story's damping.

A stiffness nonlinearity (a hardening spring, a contact stop) stores energy and gives it back:
between two levels its equivalent linear model changes a story's stiffness, the tool's
`nonlinearity` family. Two common mechanisms are not of that kind. Dry friction dissipates an
energy per cycle proportional to the amplitude, not to its square, so its equivalent viscous
damping changes with the level (for Coulomb friction c_eq = 4 F_c / (pi omega X) falls as the
amplitude X rises). A part that rests on a floor (equipment, a loose block) moves with it at one
level and slides or rattles at the other, so the floor's effective mass changes.

Each is one parameter at one place. The other level's data are fitted with every parameter of
the reference level's optimum held (damping too: friction is a change of damping) and one
parameter released: a story's stiffness, a floor's added mass, or a story dashpot of either
sign. Their chi-square drops, scaled by the level's remaining misfit, are likelihood ratios of
models of equal size; the best of one kind and the best of the others within BIC_TIE cannot be
told apart (the tie rule of candidate selection). Shear frames only: a story and a floor are
places of the model there.
"""

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from nlp.diagnosis.evidence import BIC_TIE
from nlp.diagnosis.families import AddedMass, LocalDamper
from nlp.diagnosis.fitting import best_fit, diagnosis_problem
from nlp.diagnosis.locations import is_fe

KINDS = ("stiffness", "mass", "damping")
INPUT = "__input__"   # the input record's key among a case's records (nlp.case.records)


@dataclass(frozen=True)
class StoryDashpotChange(LocalDamper):
    """A change of a story's dashpot c [N s/m] of either sign: the other level may have less
    damping than the reference (the reference's own damping is held, so C stays near it)."""

    def spec(self, ref):
        c = ref["c_ref"]
        return {"initial": [0.0], "lower": [-50.0 * c], "upper": [50.0 * c], "scale": [c],
                "null": [0.0]}


@dataclass(frozen=True)
class CommonStiffness:
    """Every story's stiffness times (1 + g) [-]: a change shared by all stories, as slightly
    nonlinear joints in every story give when they all soften alike. Released beside one
    story (release's ``extra``), that story's change is its departure from the shared one."""

    family = "common_stiffness"
    names = ("g",)
    location = {}

    def spec(self, ref):
        return {"initial": [0.0], "lower": [-0.5], "upper": [0.5], "scale": [0.01], "null": [0.0]}

    def apply(self, sys, th, ref):
        n = ref["K_parts"][0].shape[0]
        K = ca.SX(sys["K"])
        K[:n, :n] = (1 + th[0]) * K[:n, :n]
        return {**sys, "K": K}


def applies(ref):
    """Whether the kinds can be told on this model: a shear frame, a stiffness per story."""
    model = ref["case"].model
    sa, _, _ = ref["problem"].params.slices()
    return not is_fe(model) and sa.stop - sa.start == model.n


def release(src, dst, kind, index, extra=()):
    """dst's data at src's optimum (every parameter held, damping too), one released.

    kind: "stiffness" (story index+1's theta), "mass" (an added mass at floor index+1),
    "damping" (a dashpot change across story index+1) or None (only ``extra``). extra:
    enrichments released beside it. Returns the refit's chi-square, the released value
    (theta, kg, N s/m; extra's first parameter when kind is None) and whether it converged.
    """
    pr_d = dst["problem"]
    sa, _, _ = pr_d.params.slices()
    theta_s = src["problem"].theta(src["z"])
    free = sa.start + index if kind == "stiffness" else None
    params = replace(pr_d.params, params=tuple(
        p if (p.fixed or i == free) else replace(p, fixed=True, initial=float(theta_s[i]))
        for i, p in enumerate(pr_d.params.params)))
    enr = {"stiffness": (), "mass": (AddedMass(index + 1),), None: (),
           "damping": (StoryDashpotChange(index + 1, index),)}[kind] + tuple(extra)
    c = dst["case"]
    # one free parameter: the SX graph evaluated as it is costs 0.2-0.3 s a refit, less
    # than compiling it
    pr = diagnosis_problem(c, pr_d.target, enrichments=enr, compile=False,
                           damping=(c.damping, params))
    start = np.zeros(pr.params.n_theta)
    start[:theta_s.size] = theta_s
    res = best_fit(pr, [pr.params.z_from_theta(start)])
    th = pr.theta(res.z)
    # the kind's own enrichment comes first after the case's parameters, then extra's
    return (float(2 * res.f), float(th[free] if free is not None else th[theta_s.size]),
            bool(res.success))


def _held(src, dst):
    pr = dst["problem"]
    return float(2 * pr.objective(pr.params.z_from_theta(src["problem"].theta(src["z"]))))


def level_kind(ref, lv, phi_ref, phi_lv, order=None):
    """Which one-parameter change at one place best explains the difference between levels.

    Both ways round: the other level's data at the reference optimum, and the reference's
    data at the other level's optimum, each drop scaled by its data's remaining misfit
    (phi_lv, phi_ref) and the two summed, so that neither level is privileged (which one is
    the reference is the user's choice). order: +1 when the other level is the higher, -1
    when the lower, None when not known. Returns every release, the best of each kind, and
    the decision ("kind", "index", "tied_with", "margin"); "change" is the released
    parameter's change from the reference level to the other (the mean of the two ways),
    and "rises" whether it grows with the level (None when the order is not known).
    """
    n = ref["case"].model.n
    held = {"other": _held(ref, lv) / phi_lv, "reference": _held(lv, ref) / phi_ref}
    theta = {"reference": ref["problem"].theta(ref["z"]), "other": lv["problem"].theta(lv["z"])}
    sa, _, _ = ref["problem"].params.slices()
    rows = []
    for kind in KINDS:
        for i in range(n):
            chi_o, v_o, ok_o = release(ref, lv, kind, i)
            chi_r, v_r, ok_r = release(lv, ref, kind, i)
            if kind == "stiffness":   # relative changes of the held level's stiffness
                v_o, v_r = v_o - theta["reference"][sa.start + i], v_r - theta["other"][sa.start + i]
            rows.append({"kind": kind, "index": i,
                         "drop": held["other"] - chi_o / phi_lv + held["reference"] - chi_r / phi_ref,
                         "change": 0.5 * (v_o - v_r), "changes": [v_o, -v_r],
                         "converged": ok_o and ok_r})
    best = {k: max((r for r in rows if r["kind"] == k), key=lambda r: r["drop"]) for k in KINDS}
    out = {"held_chi2": held, "releases": rows, "best": best, **decide_kind(best)}
    top = best[out["kind"]] if out["kind"] else None
    out["rises"] = None if top is None or order is None or np.sign(top["changes"][0]) != np.sign(
        top["changes"][1]) else bool(top["change"] * order > 0)
    return out


def decide_kind(best):
    """The kind whose best release beats every other kind's best by more than BIC_TIE, from
    a converged refit; otherwise None, with the kinds that tie with the best."""
    order = sorted(best.values(), key=lambda r: -r["drop"])
    top = order[0]
    ties = [r["kind"] for r in order[1:] if top["drop"] - r["drop"] <= BIC_TIE]
    decided = not ties and top["converged"]
    return {"kind": top["kind"] if decided else None, "index": top["index"],
            "tied_with": ties, "margin": float(top["drop"] - order[1]["drop"])}


def level_order(ref, lv):
    """+1 when the other level's input record is the stronger (RMS), -1 when the weaker,
    None without input records (FRF files carry no level)."""
    a, b = (getattr(f["case"].records, "data", {}).get(INPUT) for f in (ref, lv))
    if a is None or b is None:
        return None
    ra, rb = float(np.sqrt(np.mean(np.square(a)))), float(np.sqrt(np.mean(np.square(b))))
    return None if ra == rb else (1 if rb > ra else -1)


def location(kind, index):
    """The finding's location: story index+1 between two floors, or floor index+1."""
    return {"floor": index + 1} if kind == "mass" else {"between": [index, index + 1]}


def _place(kind, index):
    if kind == "mass":
        return f"floor {index + 1}"
    return f"story {index + 1} (between {'the ground' if index == 0 else f'floor {index}'} " \
           f"and floor {index + 1})"


def changed(b):
    """A release's change from the reference level to the other, in its unit."""
    label, unit = {"stiffness": ("stiffness", "% of its nominal"), "mass": ("mass", "kg"),
                   "damping": ("dashpot", "N s/m")}[b["kind"]]
    v = 100 * b["change"] if b["kind"] == "stiffness" else b["change"]
    return f"{label} change {v:+.3g} {unit}"


def kind_statement(k):
    """What changes with the level, in plain words."""
    b = k["best"]
    if k["kind"] is None:
        top = max(b.values(), key=lambda r: r["drop"])
        tied = [b[t] for t in k["tied_with"]]
        return ("What changes with the level cannot be told apart: "
                + " and ".join(f"the {r['kind']} of {_place(r['kind'], r['index'])}"
                               for r in [top] + tied)
                + f" explain the difference within {BIC_TIE:g} of each other (chi-square drops, "
                  "scaled, of one parameter freed between the levels).")
    top = b[k["kind"]]
    rest = max((r for r in b.values() if r is not top), key=lambda r: r["drop"])
    lead = (f"The {k['kind']} of {_place(k['kind'], k['index'])}, freed alone between the levels, "
            f"explains the difference better than any other story's or floor's stiffness, mass "
            f"or damping (chi-square drop {top['drop']:.0f} against {rest['drop']:.0f}, scaled; "
            f"{changed(top)} at the other level")
    if k["kind"] == "stiffness":
        return lead + ")."
    trend = {True: "rising with the level", False: "falling as the level rises",
             None: "the order of the levels is not known"}[k["rises"]]
    lead += f", {trend})."
    friction = ("Dry friction or slip in a joint does this: the equivalent damping of dry "
                "friction falls as the amplitude rises.")
    spread = ("A stiffness nonlinearity under random excitation spreads its resonance over the "
              "stiffnesses its amplitudes visit, which raises the damping with the level, and so "
              "does slip that starts at the higher level")
    if k["kind"] == "mass":
        why = ("A part that moves with the floor at one level and slides, lifts or rattles at the "
               "other does this.")
    elif k["rises"] is False:
        why = friction
    else:
        return (f"{lead} {friction if k['rises'] is None else ''} {spread}: the data of two levels "
                "do not tell these apart, so the mechanism is not decided.").replace("  ", " ")
    return (f"{lead} {why} No family of the tool describes it: the equivalent linear model of "
            "each level is given, and the mechanism is not modelled.")


def with_kind(ref, lv, finding, phis, log, k=None):
    """The nonlinearity finding with what changes with the level (finding["mechanism"]); a
    change of mass or damping moves the finding to its place and says that no family
    describes it. Unchanged where the kinds do not apply (FE models). k: the kind, when
    already decided (:func:`level_kind`)."""
    if not applies(ref):
        return finding
    if k is None:
        k = level_kind(ref, lv, *phis, level_order(ref, lv))
    mech = {"kind": k["kind"], "index": k["index"], "tied_with": k["tied_with"],
            "margin": k["margin"], "rises": k["rises"], "held_chi2": k["held_chi2"],
            "best": {n: dict(r) for n, r in k["best"].items()}}
    out = dict(finding, mechanism=mech, statement=finding["statement"] + " " + kind_statement(k))
    if k["kind"] in ("mass", "damping"):
        out["location"] = location(k["kind"], k["index"])
    log("  what changes with the level (one parameter freed, both ways round): " + ", ".join(
        f"{r['kind']} at {_place(r['kind'], r['index']).split(' (')[0]} {r['drop']:.0f}"
        for r in sorted(k["best"].values(), key=lambda r: -r["drop"]))
        + f": {k['kind'] or 'not decided'}")
    return out


def outside(finding):
    """Whether a nonlinearity finding's mechanism is outside the families ("outside"), not
    decided ("undecided"), or the stiffness the family describes ("stiffness").

    A mass change is outside. So is damping that falls as the level rises: dry friction's
    equivalent damping goes as 1 / amplitude, while a stiffness nonlinearity under random
    excitation spreads its resonance over the stiffnesses its amplitudes visit, which looks
    like damping that rises with the level. Damping that rises, or whose levels' order is
    not known, is therefore not decided between the two.
    """
    mech = finding.get("mechanism") or {"kind": "stiffness"}
    if mech["kind"] == "damping":
        return "outside" if mech["rises"] is False else "undecided"
    return {"stiffness": "stiffness", None: "undecided"}.get(mech["kind"], "outside")


# how the diagnosis names a level dependence by its mechanism (stiffness: the family's words)
MECHANISM_WORDS = {"mass": "a level-dependent mass (a part that slides or rattles; no family "
                           "describes it)",
                   "damping": "a level-dependent damping (friction or slip; no family "
                              "describes it)",
                   "rising damping": "a level-dependent damping, rising with the level or of "
                                     "unknown order (a stiffness nonlinearity's spread, or slip: "
                                     "not decided)",
                   "asymmetric": "a story stiffer one way than the other (a breathing crack, "
                                 "a gap or a one-sided stop; no family describes it)",
                   None: "a level dependence whose kind the data cannot tell (stiffness, mass "
                         "or damping)"}


def mechanism_words(f):
    """(title words, size words) of a nonlinearity finding whose mechanism is not the
    family's stiffness; None otherwise."""
    mech = f.get("mechanism") if f.get("physics") == "nonlinearity" else None
    if not mech or mech["kind"] == "stiffness":
        return None
    if mech["kind"] is None:
        return MECHANISM_WORDS[None], None
    if mech["kind"] == "asymmetric":   # nlp.diagnosis.asymmetry
        d = f["parameters"].get("bilinear_delta")
        return MECHANISM_WORDS["asymmetric"], (
            f"about {100 * d:.0f} % softer when {mech['softer_when']} (bilinear reading)"
            if d is not None else f"softer when {mech['softer_when']}")
    key = "rising damping" if outside(f) == "undecided" else mech["kind"]
    return MECHANISM_WORDS[key], changed(mech["best"][mech["kind"]]) + " between the levels"
