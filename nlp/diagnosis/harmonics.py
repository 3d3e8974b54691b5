"""Where a nonlinearity acts, from the response outside the excitation band.

A linear structure responds only at the frequencies it is driven at. A nonlinear
element across story s (a cubic spring, a contact with a gap) adds a restoring
force f_nl(t) with the story's pattern b_s (K_s = k_s b_s b_s^T), and its
harmonics fall where the input has no power. There the outputs, less the linear
model's response to the measured input, are

    r(omega) = G(omega) b_s F(omega) + noise,

one unknown complex force F per frequency: the ratios between the channels are
fixed by the story. Above the last mode G is close to the mass line, so the floors
on either side of the element respond in opposite directions and the others hardly
at all; a single equivalent stiffness per level cannot say this (its change is
spread over the stories that move each mode, and on one-segment chirps the
score test of :func:`nlp.diagnosis.levels.level_location` has put a contact one story
off; see docs/method/diagnosis.md).

Each channel is whitened by its noise level out of band (the median power over
those bins / ln 2: the bins hold noise except for the harmonics). For each story
the power a single force with its pattern explains is summed over the bins,
``captured_s = sum K (g^H S g / g^H g - 1)``, with S the whitened cross-spectral
matrix of the K segments; ``excess = sum K (tr S - n_ch)`` is the out-of-band power
above the noise. Units: noise variances (a chi-square-like scale).
"""

import math

import numpy as np
from scipy.signal import get_window

from nlp.frf.forms import POWER
from nlp.frf.reference import BASE_DOF

__all__ = ["story_vectors", "story_matrix", "force_frfs", "out_of_band", "harmonic_location",
           "MIN_EXCESS_Z", "MIN_SHARE", "MIN_GAP"]

MIN_EXCESS_Z = 10.0  # out-of-band power above noise, in standard deviations of its noise-only sum
MIN_SHARE = 0.5      # the best story's force explains at least half of that power
MIN_GAP = 25.0       # ... and this much more than the next story (likelihood-ratio scale)


def story_vectors(K_groups, tol=1e-9):
    """The force pattern b of each rank-one stiffness group (K_j = b b^T up to scale);
    None for a group of higher rank (no single element to locate)."""
    out = []
    for Kj in K_groups:
        A = Kj.toarray() if hasattr(Kj, "toarray") else np.asarray(Kj, float)
        w, v = np.linalg.eigh(0.5 * (A + A.T))
        big = np.abs(w) > tol * max(float(np.max(np.abs(w))), 1e-300)
        out.append(v[:, int(np.argmax(np.abs(w)))] if big.sum() == 1 else None)
    return out


def story_matrix(model, n_dof):
    """(groups, B): the stiffness groups with a single force pattern (story_vectors) and
    their patterns as the columns of B, padded with zeros to n_dof (a model's extra DOFs:
    appendages, a base); (groups, None) when there is none (an FE model's groups)."""
    bs = story_vectors(model.K_infl)
    groups = [j for j, b in enumerate(bs) if b is not None]
    if not groups:
        return groups, None
    B = np.column_stack([bs[j] for j in groups])
    return groups, np.vstack([B, np.zeros((n_dof - model.n, B.shape[1]))])


def force_frfs(M, C, K, omega, B, channels):
    """Channel outputs per unit internal force with pattern B[:, s]: (N, n_ch, n_s) complex.

    Receptance X, mobility j omega X, accelerance (relative or absolute: the ground does
    not move under an internal force) -omega^2 X; a base channel sees nothing.
    """
    omega = np.asarray(omega, float)
    out = np.zeros((omega.size, len(channels), B.shape[1]), complex)
    for i, w in enumerate(omega):
        X = np.linalg.solve(K - w * w * M + 1j * w * C, B)
        for c, ch in enumerate(channels):
            if ch.dof != BASE_DOF:
                out[i, c] = (1j * w) ** POWER[ch.output] * X[ch.dof]
    return out


def _segments(x, nperseg, window):
    n = x.size
    step = max(nperseg // 2, 1) if nperseg < n else n
    starts = range(0, n - nperseg + 1, step)
    w = get_window(window, nperseg) if nperseg < n else np.ones(n)
    return np.array([np.fft.rfft(w * x[s:s + nperseg]) for s in starts])


def out_of_band(f, U, f_top, fs, frac=1e-2, margin=1.05, nyquist_use=0.8):
    """Bins above the excitation band: above both f_top (the fitted band) and the last bin
    where the input's segment-averaged power exceeds ``frac`` of its 90th percentile over
    the fitted band, and below ``nyquist_use`` of the Nyquist frequency (anti-alias filters)."""
    P = np.mean(np.abs(U) ** 2, axis=0)
    inband = f <= f_top
    ref = np.percentile(P[inband], 90) if inband.any() else P.max()
    driven = np.nonzero(P > frac * ref)[0]
    top = max(f_top, f[driven].max() if driven.size else 0.0)
    return np.nonzero((f > margin * top) & (f < nyquist_use * fs / 2))[0]


def harmonic_location(tests, M, C, K, B, channels, f_top):
    """Which internal force pattern explains the out-of-band response of the tests.

    tests : iterable of (records, H_model) with records an nlp.io.readers.TimeHistories (SI,
        ``__input__`` and one record per channel name) and H_model(omega) -> (n_ch, N) the
        linear model's channel FRFs; plus ``nperseg`` and ``window`` attributes of the
        estimate, given as keys "nperseg" (int or None for the whole record), "window".
    M, C, K : the linear model; B : (n, n_s) force patterns (columns; None excluded before);
    f_top : [Hz] top of the fitted band.

    Returns a dict with per-pattern ``captured`` and ``share`` of the ``excess`` power,
    ``z_excess`` (excess in standard deviations of a noise-only sum), ``best`` (index or
    None when the evidence does not decide: see MIN_EXCESS_Z, MIN_SHARE, MIN_GAP) and the
    number of bins used.
    """
    captured = np.zeros(B.shape[1])
    excess, n_terms, n_bins = 0.0, 0, 0
    for t in tests:
        rec, Hm = t["records"], t["H_model"]
        x = np.asarray(rec.data["__input__"], float)
        nseg = x.size if t.get("nperseg") in (None, "all") else min(int(t["nperseg"]), x.size)
        win = t.get("window") or "hann"
        f = np.fft.rfftfreq(nseg, 1.0 / rec.fs)
        U = _segments(x, nseg, win)
        idx = out_of_band(f, U, f_top, rec.fs)
        if idx.size < 8:
            continue
        Y = np.array([_segments(np.asarray(rec.data[ch.name], float), nseg, win)[:, idx]
                      for ch in channels])                        # (n_ch, K, n_idx)
        w = 2 * np.pi * f[idx]
        R = Y - Hm(w)[:, None, :] * U[None, :, idx]               # less the linear response
        sig2 = np.median(np.abs(R) ** 2, axis=(1, 2)) / math.log(2.0)
        keep = sig2 > 0
        if not keep.any():
            continue
        R = R[keep] / np.sqrt(sig2[keep])[:, None, None]
        G = force_frfs(M, C, K, w, B, [c for c, k in zip(channels, keep) if k])
        G = G / np.sqrt(sig2[keep])[None, :, None]                # (n_idx, n_ch, n_s)
        nk = R.shape[1]
        S = np.einsum("ckf,dkf->fcd", R, R.conj()) / nk           # (n_idx, n_ch, n_ch)
        tr = np.real(np.einsum("fcc->f", S))
        gg = np.real(np.einsum("fcs,fcs->fs", G.conj(), G))
        gSg = np.real(np.einsum("fcs,fcd,fds->fs", G.conj(), S, G))
        captured += nk * np.sum(gSg / np.maximum(gg, 1e-300) - 1.0, axis=0)
        excess += nk * float(np.sum(tr - keep.sum()))
        n_terms += nk * idx.size * int(keep.sum())
        n_bins += idx.size
    z = excess / math.sqrt(max(n_terms, 1))
    share = captured / excess if excess > 0 else np.zeros_like(captured)
    order = np.argsort(captured)[::-1]
    best = int(order[0]) if captured.size else None
    gap = float(captured[order[0]] - captured[order[1]]) if captured.size > 1 else float("inf")
    decided = (best is not None and z > MIN_EXCESS_Z and share[best] > MIN_SHARE
               and 2 * gap > MIN_GAP)
    return {"captured": captured.tolist(), "share": share.tolist(), "excess": excess,
            "z_excess": z, "gap": gap, "bins": n_bins,
            "best": best if decided else None, "best_raw": best}
