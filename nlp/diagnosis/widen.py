"""When a look widens its windows, and the windows a widened look fits.

The fit only sees its half-power windows; an effect that lives between the resonances
(e.g. an appendage tuned between two modes) shows in the held-out shoulders. A look is
repeated over windows 3x wider (WIDEN) when

* nothing is found and the shoulders carry the mismatch (off_peak), or
* one finding explains the windows but leaves the shoulders above HELD_LEFT
  (leaves_shoulders); that widened look stands only if it keeps the finding
  (keeps_findings), or refutes it: refitted there, it predicts the wider shoulders worse
  than the model without it (refuted_on_wider).

A widened look also fits a window of HOT_WINDOW around each of the largest misfits off
the windows (band.hot_spots) and the resonances the model lacks (hot_windows).
"""

import numpy as np

from nlp.case.selection import selectable
from nlp.diagnosis.decide import adequate, windows_explained

WIDEN = 3           # the widened look's windows, in half-power bandwidths of the first's
HOT_WINDOW = 0.06   # half-width (relative) of the window the widened look fits around a hot spot
# Held-out chi-square above which findings that explain their windows leave the shoulders
# unexplained (the held-out half of decide.adequate), so the windows are widened and
# looked at again
HELD_LEFT = 2.0
OFF_PEAK_RATIO = 3  # shoulders' mean z^2 over the windows' reduced chi-square: "far worse"


def hot_windows(cfg, case, fit, held, hot, log):
    """The fitted and held-out points with windows of HOT_WINDOW (and 3x that, held out)
    around each hot frequency [Hz], kept to the case's band and coherence rule: the fit
    only sees its windows, so an effect between the resonances must be in them, and a
    window at the top of the excitation band must not fit points the case rules out
    (incoherent points above fmax)."""
    ok = selectable(cfg, case.f, case.channels, case.coherence)
    near = [np.flatnonzero((np.abs(case.f / h - 1.0) <= w * HOT_WINDOW) & ok)
            for h in hot for w in (1, 3)]
    fit = np.union1d(fit, np.concatenate(near[0::2]))
    held = np.union1d(held, np.concatenate(near[1::2]))
    used = [h for h, n in zip(hot, near[0::2]) if n.size]
    if used:
        log("also fitting the largest misfits off the windows: "
            + ", ".join(f"{h:.3g} Hz +- {100 * HOT_WINDOW:.0f} %" for h in used))
    return fit, held


def off_peak(base, sel):
    """Nothing found, and the mismatch lives in the held-out shoulders: the windows are
    explained while the shoulders are not, or the shoulders are far worse."""
    shoulders = (windows_explained(base.chi, base.nu)
                 or base.held > OFF_PEAK_RATIO * base.chi / base.nu)
    return (not sel.found and not sel.indistinct and shoulders
            and not adequate(base.chi, base.nu, base.held))


def leaves_shoulders(base, sel, k_now):
    """One finding (k_now parameters added) explains the windows but leaves the held-out
    shoulders above HELD_LEFT: what remains lies between the windows.

    One finding only: the wider look costs about a second diagnosis over 3x the points,
    and a first look that placed two effects has spent two rounds already (measured: a
    benchmark case with two findings spent most of its time budget in the widened look;
    see docs/method/diagnosis.md)."""
    nu_now = max(base.nu - k_now, 1)
    state = sel.state
    return (len(sel.found) == 1 and not sel.indistinct
            and windows_explained(state["chi"], nu_now) and state["held"] > HELD_LEFT)


def keeps_findings(result, found):
    """Whether a widened look's result names every finding of the first look, or refutes
    each one it does not name (refuted_on_wider): then the wider look stands too."""
    keys = {(f["physics"], repr(f["location"])) for f in result.get("findings", [])}
    gone = {(f["physics"], repr(f["location"])) for f in result.get("unconfirmed", [])
            if "widened_look" in f.get("evidence", {})}
    return all((r["physics"], repr(r["location"])) in keys | gone for r in found)


def refuted_on_wider(sel, held_without):
    """The first look's finding as a seeded widened look re-proved it first (sel.tried[0]),
    when it was refused there with held-out shoulders worse than the wider baseline's
    (held_without): it then predicts the data no fit used worse than the model without it,
    so it is not a finding (listed unconfirmed, with both figures). None otherwise: a
    finding refused on other grounds (a tie, a cut short of 20 %) keeps the first look."""
    if not sel.tried or sel.tried[0]["accepted"] or sel.tried[0]["held_out"] <= held_without:
        return None
    r = sel.tried[0]
    return dict(r, widened={"held_out": r["held_out"], "held_out_without": held_without},
                why_not="on windows 3x wider it predicts the held-out shoulders worse than the "
                        "model without it")
