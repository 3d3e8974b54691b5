"""Figures: FRF overlays of initial, experimental and updated models (Figure 6).

Figures are built on :class:`matplotlib.figure.Figure` with no pyplot, so
importing the package never switches a notebook's backend; PNGs are written
by the Agg canvas.
"""

import os

import numpy as np
from matplotlib.figure import Figure

from nlp.frf.forms import QUANTITY
from nlp.frf.reference import channel_frfs

__all__ = ["plot_frf_overlays", "save_figure", "new_figure", "frf_quantity", "MIN_PHASE_COHERENCE"]

MIN_PHASE_COHERENCE = 0.5   # below it the measured phase is noise: not drawn


def frf_quantity(output, excitation):
    """FRF quantity in words and its SI unit, e.g. ``("floor acceleration per force
    (accelerance)", "(m/s^2)/N")``.

    For ground input the FRF is per unit ground acceleration, and the response is
    relative to the ground except ``absolute_accelerance`` (Eqns 16-19).
    """
    what, unit = QUANTITY[output]
    if excitation == "force":
        return f"{what} per force ({output})", f"({unit})/N" if "/" in unit else f"{unit}/N"
    rel = "" if output == "absolute_accelerance" else "relative "
    ratio = {"m": "s^2", "m/s": "s", "m/s^2": "-"}[unit]
    return f"{rel}{what} per ground acceleration ({output.replace('_', ' ')})", ratio


def new_figure(**kwargs):
    """A Figure not registered with pyplot (no global state, no backend switch)."""
    return Figure(**kwargs)


def save_figure(fig, path, dpi=110):
    """Write a figure atomically (temporary file, then rename); returns the path."""
    tmp = os.path.join(os.path.dirname(path) or ".", ".tmp-" + os.path.basename(path))
    try:
        fig.savefig(tmp, dpi=dpi, format="png")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):  # a failed save leaves no empty .tmp-* behind
            os.unlink(tmp)
    return path


def _db(H):
    with np.errstate(divide="ignore"):
        return 20 * np.log10(np.abs(H))


def plot_frf_overlays(out_dir, case, initial, updated):
    """One PNG per channel: |H| in dB and phase, measured vs initial vs updated.

    initial, updated : (M, K, C) tuples. Points used in the objective are
    marked. Files are written atomically; returns their paths.
    """
    tg = case.target
    f_sel = tg.omega / (2 * np.pi)
    hi = min(case.f[-1], 1.5 * f_sel.max())
    keep = (case.f > 0) & (case.f <= hi)
    f = case.f[keep]
    w = 2 * np.pi * f
    H0 = channel_frfs(initial[0], initial[2], initial[1], w, case.channels, tg.excitation,
                      tg.force_dof, tg.ground_r)
    H1 = channel_frfs(updated[0], updated[2], updated[1], w, case.channels, tg.excitation,
                      tg.force_dof, tg.ground_r)
    Hx = case.H[:, keep]
    coh = None if case.coherence is None else case.coherence[:, keep]
    paths = []
    for c, ch in enumerate(case.channels):
        fig = new_figure(figsize=(7.5, 6.2), layout="constrained")
        a1, a2 = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
        words, unit = frf_quantity(ch.output, tg.excitation)
        a1.plot(f, _db(Hx[c]), color="0.35", lw=1.0, label="measured")
        a1.plot(f, _db(H0[c]), "--", color="tab:blue", lw=1.2, label="initial model")
        a1.plot(f, _db(H1[c]), color="tab:red", lw=1.4, label="updated model")
        a1.plot(f_sel, _db(tg.H[c]), ".", color="k", ms=3, label="points fitted")
        a1.set_ylabel(f"magnitude [dB re 1 {'(ratio)' if unit == '-' else unit}]")
        where = ("input: ground acceleration" if tg.excitation == "ground"
                 else f"input: force at DOF {(tg.force_dof if ch.force_dof is None else ch.force_dof) + 1}")
        a1.set_title(f"{ch.name}: {words}\nresponse at DOF {ch.dof + 1}, {where}", fontsize=10)
        a1.legend(loc="best", fontsize=8)
        a1.grid(alpha=0.3)
        if case.has_phase:
            ph = np.degrees(np.angle(Hx[c]))
            if coh is not None:  # phase only where the input explains the output
                ph = np.where(coh[c] >= MIN_PHASE_COHERENCE, ph, np.nan)
            a2.plot(f, ph, ".", color="0.35", ms=2.5, label="measured")
        else:
            a2.text(0.5, 0.9, "measured: magnitude only (no phase)", transform=a2.transAxes,
                    ha="center", fontsize=8, color="0.35")
        a2.plot(f, np.degrees(np.angle(H0[c])), "--", color="tab:blue", lw=1.2)
        a2.plot(f, np.degrees(np.angle(H1[c])), color="tab:red", lw=1.4)
        a2.set_ylabel("phase [deg]")
        a2.set_xlabel("frequency [Hz]")
        a2.set_yticks([-180, -90, 0, 90, 180])
        a2.set_ylim(-195, 195)
        if coh is not None:
            a2.set_title(f"measured phase shown where coherence >= {MIN_PHASE_COHERENCE}",
                         fontsize=8, loc="left")
        a2.grid(alpha=0.3)
        paths.append(save_figure(fig, os.path.join(out_dir, f"frf_{ch.name}.png")))
    return paths
