"""Nuisance parameters the data leave open: held at a stated value, the finding judged again.

An appendage's damping ratio and a flexible base's mass and dashpot shape a resonance
without measuring the effect (nlp.diagnosis.evidence.NUISANCE). When one of them has a
standard error above its value, its estimate is noise, and so is every number that traded
against it. Such a candidate is refitted with those parameters held at a stated physical
reference (:func:`reference`) and judged again on that refit by the same rules (scaled BIC,
significance, held-out test). It is accepted only if it still passes; its report then lists
the held parameter as an assumption, never as an estimate.
"""

import math
from dataclasses import dataclass

import casadi as ca

from nlp.diagnosis.evidence import BIC_ACCEPT, undetermined
from nlp.diagnosis.fitting import case_references
from nlp.diagnosis.refit import refit

__all__ = ["Held", "reference", "hold", "open_nuisance", "settle",
           "hold_open_nuisance", "why_refused"]

@dataclass(frozen=True)
class Held:
    """A structural family with some parameters held at stated values: they are constants
    of its CasADi graph, not decision variables (no error, no BIC count).

    inner : the family (nlp.diagnosis.families) whose ``apply`` builds the system.
    values : ((name, value), ...) of the held parameters, in inner's units.
    """

    inner: object
    values: tuple

    @property
    def family(self):
        return self.inner.family

    @property
    def location(self):
        return self.inner.location

    @property
    def held(self):
        """{name: value} of the held parameters."""
        return dict(self.values)

    @property
    def names(self):
        return tuple(n for n in self.inner.names if n not in self.held)

    def _free(self):
        return [i for i, n in enumerate(self.inner.names) if n not in self.held]

    def spec(self, ref):
        """The inner family's spec without the held parameters."""
        keep = self._free()
        return {key: [v[i] for i in keep] for key, v in self.inner.spec(ref).items()}

    def starts(self, ref):
        """The inner family's start points without the held parameters, each once."""
        keep = self._free()
        out = []
        for s in (self.inner.starts(ref) if hasattr(self.inner, "starts") else []):
            p = [s[i] for i in keep]
            if p not in out:
                out.append(p)
        return out

    def full(self, th):
        """The inner family's parameter vector: the free ones th, the held ones constants."""
        held, it = self.held, iter(range(len(self.names)))
        return ca.vertcat(*[held[n] if n in held else th[next(it)] for n in self.inner.names])

    def apply(self, sys, th, ref):
        """The inner family's change of the system, its held parameters as constants."""
        return self.inner.apply(sys, self.full(th), ref)

    def __getattr__(self, name):
        # the family's own attributes (floor, f0) for code that reads them; never the
        # dataclass's fields or special names (pickling looks those up before they exist)
        if name.startswith("__") or name in ("inner", "values"):
            raise AttributeError(name)
        return getattr(self.inner, name)


# A held value the data exclude would be an assumption the fit contradicts: its refit then
# trades the other parameters against it (a base dashpot held at 25 times the largest value
# the data allowed doubled the chi-square of its refit). The data allow the
# values within ALLOWED_Z standard errors of the free estimate: a two-sided 95 % interval
# of the Gauss-Newton estimate, the linearised likelihood-ratio test at that level.
ALLOWED_Z = 2.0


def reference(e, names, refs, free=None):
    """{name: value}: the value each of e's parameters `names` is held at, the family's own
    start (spec(refs)["initial"]): a stated physical reference, not a fitted value. An
    appendage's damping ratio 0.02 (light structural damping), a base of half the mean floor
    mass, a base dashpot of c_ref (the mean diagonal of the case's damping matrix), or 0 under
    a Rayleigh law, which already damps the base (families.BaseFlexibility).

    free : the family's free refit result, or None. A reference outside the values its data
    allow (estimate +- ALLOWED_Z standard errors) is replaced by the nearest value they allow,
    so a held parameter is never one the data exclude; always within the family's bounds."""
    sp = e.spec(refs)
    out = {}
    for n, v, lo, hi in zip(e.names, sp["initial"], sp["lower"], sp["upper"]):
        if n not in names:
            continue
        v = float(v)
        est = (free or {}).get("parameters", {}).get(n)
        se = (free or {}).get("uncertainty", {}).get(n)
        if est is not None and se is not None and math.isfinite(se):
            v = min(max(v, est - ALLOWED_Z * se), est + ALLOWED_Z * se)
        out[n] = min(max(v, float(lo)), float(hi))
    return out


def hold(e, names, refs, free=None):
    """e with its parameters `names` held at their reference values (on top of any e holds
    already); free: e's free refit result (:func:`reference`)."""
    inner, held = (e.inner, e.held) if isinstance(e, Held) else (e, {})
    held.update(reference(e, names, refs, free))
    return Held(inner, tuple((n, held[n]) for n in inner.names if n in held))


def open_nuisance(r):
    """Names of a refit result's nuisance parameters whose standard error exceeds their
    value or is not a number (nlp.diagnosis.evidence.undetermined)."""
    names = list(r["parameters"])
    return undetermined(r["physics"], names, [r["parameters"][n] for n in names],
                        [r["uncertainty"][n] for n in names])


def _said(held):
    return ", ".join(f"{n} held at {v:.4g}" for n, v in held.items())


def why_refused(r):
    """Why a judged result is not accepted, in words."""
    if not r["significant"]:
        return r["why_not"]
    if r["at_bound"]:
        on = [f"{n} = {r['parameters'][n]:.4g}" for n in r.get("on_bound", ())
              if n in r["parameters"]]
        return f"{', '.join(on) or 'a parameter'} on the bound of its family's range"
    if r["delta_bic"] > -BIC_ACCEPT:
        return f"its scaled BIC change {r['delta_bic']:.1f} is above -{BIC_ACCEPT:g}"
    return f"its held-out chi-square {r['held_out']:.2f} fails the held-out test"


def hold_open_nuisance(results, judge, job, log=print):
    """:func:`settle` with the round's refit: job = (case, target, current, z_cur, n_fit,
    held, sig_held), the arguments of nlp.diagnosis.refit.refit other than the candidate and
    its score."""
    case, target, current, z_cur, n_fit, held, sig_held = job
    return settle(results, judge, lambda r, e: refit(case, target, current, z_cur, e, r["score"],
                                                     n_fit, held, sig_held),
                  case_references(case), log)


def settle(results, judge, refit_held, refs, log=print):
    """Judge a round's refits; every accepted one whose nuisance parameters the data leave
    open is replaced by its refit with them held at their reference values (hold) and the
    round is judged again, until no accepted result has an open nuisance parameter.

    judge : results -> phi, the round's decision (nlp.diagnosis.decide.decide, bound to its
        reference chi-square and degrees of freedom); it sets "accepted" on every result.
    refit_held : (result, held family) -> the refit of that family (nlp.diagnosis.refit.refit
        with the result's round and score).
    A held result carries r["held"] = {name: value}; one that no longer passes is rejected
    with r["why_not"] naming what was held. Returns the last judge's phi.
    """
    phi = judge(results)
    while True:
        todo = [(i, open_nuisance(r)) for i, r in enumerate(results) if r["accepted"]]
        todo = [(i, names) for i, names in todo if names]
        if not todo:
            return phi
        for i, names in todo:
            e = hold(results[i]["enrichment"], names, refs, results[i])
            stated = reference(results[i]["enrichment"], names, refs)
            new = refit_held(results[i], e)
            new["held"] = e.held
            moved = {n: v for n, v in stated.items() if v != e.held[n]}
            if moved or results[i].get("held_reference"):
                new["held_reference"] = {**results[i].get("held_reference", {}), **moved}
            results[i] = new
        phi = judge(results)
        for r in results:   # judge clears every reason: a held refusal says what was held
            if r.get("held") and not r["accepted"]:
                r["why_not"] = (f"with {_said(r['held'])} (the data do not determine it), "
                                f"{why_refused(r)}")
        for i, _ in todo:
            r = results[i]
            log(f"    {r['physics']} {r['location']}: {_said(r['held'])} (the data do not "
                f"determine it): dBIC {r['delta_bic']:.1f}, held-out {r['held_out']:.2f}, "
                + ("still passes" if r["accepted"] else f"not accepted: {r['why_not']}"))
