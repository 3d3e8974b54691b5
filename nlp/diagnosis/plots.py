"""Figures of a diagnosis: residual maps before/after and FRF overlays."""

import os
import textwrap

import numpy as np

from nlp.diagnosis.units import FAMILY_WORDS
from nlp.output.plots import frf_quantity, new_figure, save_figure

__all__ = ["plot_diagnosis"]


def _grid(cells, key):
    chans = list(dict.fromkeys(c["channel"] for c in cells))
    bands = list(dict.fromkeys(tuple(c["band_hz"]) for c in cells))
    G = np.full((len(chans), len(bands)), np.nan)
    for c in cells:
        v = c[key]
        G[chans.index(c["channel"]), bands.index(tuple(c["band_hz"]))] = np.nan if v is None else v
    return chans, bands, G


def plot_diagnosis(out, case, base, z_base, improved, z_imp, before, after, family):
    """residual_map.png (fitted and held-out, before and after) and frf_diagnosis_<ch>.png."""
    fig = new_figure(figsize=(10, 6.5), layout="constrained")
    axes = fig.subplots(2, 2, squeeze=False)
    for row, (cells, title) in enumerate(((before, "baseline"), (after, "with added physics"))):
        for col, key in enumerate(("fitted", "held_out")):
            chans, bands, G = _grid(cells, key)
            ax = axes[row, col]
            im = ax.imshow(np.log10(np.maximum(G, 1e-2)), vmin=-1, vmax=2, cmap="magma_r",
                           aspect="auto")
            ax.set_yticks(range(len(chans)), chans)
            ax.set_xticks(range(len(bands)), [f"{(a + b) / 2:.3g}" for a, b in bands], fontsize=7)
            ax.set_title(f"{title}: {key.replace('_', '-')} points", fontsize=9)
            if row == 1:
                ax.set_xlabel("band centre [Hz]", fontsize=8)
    # extend: cells beyond the scale (a baseline 100x the noise and more) show as its ends
    fig.colorbar(im, ax=axes, label="log10 mean (residual / noise)^2", extend="both")
    save_figure(fig, os.path.join(out, "residual_map.png"))
    lo = case.f[case.selected].min() * 0.7
    hi = min(case.f[-1], case.f[case.selected].max() * 1.3)
    keep = (case.f >= lo) & (case.f <= hi) & (case.f > 0)
    w = 2 * np.pi * case.f[keep]
    H0 = base.channel_frfs(z_base, w)
    H1 = improved.channel_frfs(z_imp, w)
    for c, ch in enumerate(case.channels):
        fig = new_figure(figsize=(7, 4.6), layout="constrained")
        ax = fig.subplots()
        ax.semilogy(case.f[keep], np.abs(case.H[c, keep]), color="0.45", lw=3, alpha=0.5,
                    label="measured")
        ax.semilogy(case.f[keep], np.abs(H0[c]), "--", color="tab:blue", label="baseline (updated)")
        if family:
            added = ", ".join(FAMILY_WORDS.get(p, p) for p in family.split(" + "))
            ax.semilogy(case.f[keep], np.abs(H1[c]), color="tab:red",
                        label=textwrap.fill(f"with {added}", 90))
        words, unit = frf_quantity(ch.output, case.target.excitation)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"|H| [{unit}]")
        ax.set_title(f"{ch.name}: {words}", fontsize=9)
        # below the axes: a long list of added physics must not cover the curves
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
        ax.grid(alpha=0.3)
        save_figure(fig, os.path.join(out, f"frf_diagnosis_{ch.name}.png"))
