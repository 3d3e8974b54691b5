"""Figures: FRF overlays of initial, experimental and updated models (Figure 6)."""

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .frf import channel_frfs  # noqa: E402

__all__ = ["plot_frf_overlays", "save_figure"]


def save_figure(fig, path, dpi=110):
    """Write a figure atomically (temporary file, then rename) and close it."""
    tmp = os.path.join(os.path.dirname(path) or ".", ".tmp-" + os.path.basename(path))
    fig.savefig(tmp, dpi=dpi, format="png")
    os.replace(tmp, path)
    plt.close(fig)
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
    paths = []
    for c, ch in enumerate(case.channels):
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True,
                                     gridspec_kw={"height_ratios": [2, 1]})
        a1.plot(f, _db(Hx[c]), color="0.45", lw=3, alpha=0.5, label="experimental")
        a1.plot(f, _db(H0[c]), "--", color="tab:blue", lw=1.2, label="initial")
        a1.plot(f, _db(H1[c]), color="tab:red", lw=1.4, label="updated")
        a1.plot(f_sel, _db(tg.H[c]), ".", color="k", ms=3, label="points used")
        a1.set_ylabel(f"|{ch.output}| [dB]")
        a1.set_title(f"{case.config.name}: {ch.name} ({ch.output}, floor {ch.dof + 1})")
        a1.legend(loc="best", fontsize=8)
        a1.grid(alpha=0.3)
        a2.plot(f, np.degrees(np.angle(Hx[c])), color="0.45", lw=3, alpha=0.5)
        a2.plot(f, np.degrees(np.angle(H0[c])), "--", color="tab:blue", lw=1.2)
        a2.plot(f, np.degrees(np.angle(H1[c])), color="tab:red", lw=1.4)
        a2.set_ylabel("phase [deg]")
        a2.set_xlabel("frequency [Hz]")
        a2.set_yticks([-180, -90, 0, 90, 180])
        a2.grid(alpha=0.3)
        fig.tight_layout()
        paths.append(save_figure(fig, os.path.join(out_dir, f"frf_{ch.name}.png")))
    return paths
