"""Record quality: spikes and dropouts in measured time histories.

A *spike* is a glitch of single samples that stands out from its neighbours.
Each sample is compared with the cubic through the two samples on each side,
``r_i = x_i - (-x_{i-2} + 4 x_{i-1} + 4 x_{i+1} - x_{i+2}) / 6`` (exact for a
cubic, so a smooth, oversampled response leaves only its noise), scaled by the
robust standard deviation of ``r`` (1.4826 x its median absolute value, so a
few percent of glitches do not mask themselves). A spike of height A also
gives ``2 A / 3`` at its neighbours, and spikes close together mix, so each
cluster of samples above ``spike_threshold`` is explained by the fewest samples
(1, 2, then 3) whose least-squares replacement brings every residual of the
cluster under the threshold (the least squared residual among equals). A run
of flagged samples counts as one spike.

A *dropout* is a run of at least ``dropout_min_samples`` identical samples (a stuck or zeroed
channel): a sampled broadband response never repeats a value exactly that often.

Removal replaces the flagged samples by a cubic spline through the good
samples (linear interpolation would cut the peaks of a broadband response).
Every flagged sample is listed in the report, so a removal is always recorded.
"""

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from scipy.interpolate import CubicSpline

__all__ = ["Glitch", "QualityReport", "detect_glitches", "repair", "screen_records", "true_runs"]

SPIKE_THRESHOLD = 8.0        # robust standard deviations
DROPOUT_MIN_SAMPLES = 5      # identical samples in a row


@dataclass(frozen=True)
class Glitch:
    """One flagged stretch of samples ``start <= i < stop`` of a channel."""

    channel: str
    kind: str          # "spike" | "dropout"
    start: int
    stop: int
    time_s: float      # time of the first sample [s]


@dataclass(frozen=True)
class QualityReport:
    """What `screen_records` found and did (``to_dict`` for JSON)."""

    glitches: tuple
    n_samples: int
    removed: bool
    settings: dict = field(default_factory=dict)

    def counts(self):
        """channel -> {"spikes", "dropouts", "samples_flagged", "fraction_flagged"}."""
        out = {}
        for g in self.glitches:
            c = out.setdefault(g.channel, {"spikes": 0, "dropouts": 0, "samples_flagged": 0})
            c["spikes" if g.kind == "spike" else "dropouts"] += 1
            c["samples_flagged"] += g.stop - g.start
        for c in out.values():
            c["fraction_flagged"] = c["samples_flagged"] / max(self.n_samples, 1)
        return out

    def to_dict(self, max_listed=50):
        return {"removed": self.removed, "n_samples": self.n_samples, "settings": self.settings,
                "channels": self.counts(),
                "glitches": [{"channel": g.channel, "kind": g.kind, "start": g.start,
                              "samples": g.stop - g.start, "time_s": g.time_s}
                             for g in self.glitches[:max_listed]],
                "glitches_not_listed": max(len(self.glitches) - max_listed, 0)}


def true_runs(mask):
    """(start, stop) of the runs of True in a boolean vector."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _central(x):
    """x_i minus the cubic through x_{i-2}, x_{i-1}, x_{i+1}, x_{i+2} (0 at the ends)."""
    r = np.zeros_like(x)
    r[2:-2] = x[2:-2] - (-x[:-4] + 4 * x[1:-3] + 4 * x[3:-1] - x[4:]) / 6.0
    return r


def _central_operator(m):
    """The (m - 4, m) matrix of `_central` on a window of m samples."""
    D = np.zeros((m - 4, m))
    for i in range(m - 4):
        D[i, i:i + 5] = (1 / 6, -4 / 6, 1.0, -4 / 6, 1 / 6)
    return D


def _resolve(y, lo, hi, limit, max_spikes=3):
    """Fewest samples of y[lo:hi] (away from its two edge samples) whose least-squares
    replacement leaves every central residual of the window within ``limit``."""
    w = y[lo - 2:hi + 2]
    D = _central_operator(w.size)
    cand = range(4, w.size - 4)
    for size in range(1, max_spikes + 1):
        best, best_cost = None, np.inf
        for S in combinations(cand, size):
            S = list(S)
            keep = np.ones(w.size, bool)
            keep[S] = False
            base = D[:, keep] @ w[keep]
            vals, *_ = np.linalg.lstsq(D[:, S], -base, rcond=None)
            r = base + D[:, S] @ vals
            cost = float(r @ r)
            if np.max(np.abs(r)) <= limit and cost < best_cost:
                best, best_cost = S, cost
        if best is not None:
            return [lo - 2 + j for j in best]
    return []  # not a few spikes: leave it (a transient, or noise to be judged elsewhere)


def detect_glitches(x, spike_threshold=SPIKE_THRESHOLD, dropout_min_samples=DROPOUT_MIN_SAMPLES):
    """Spikes and dropouts of one record.

    Parameters
    ----------
    x : array_like, shape (N,)
        The record (any unit).
    spike_threshold : float
        Distance from the local cubic, in robust standard deviations.
    dropout_min_samples : int
        Shortest run of identical samples called a dropout.

    Returns
    -------
    list of (kind, start, stop)
        ``kind`` is ``"spike"`` or ``"dropout"``; samples ``start <= i < stop``.
    """
    x = np.asarray(x, dtype=float)
    out = []
    same = np.concatenate([[False], x[1:] == x[:-1]])
    stuck = np.zeros(x.size, bool)
    for a, b in true_runs(same):       # a run of repeats starts one sample earlier
        if b - a + 1 >= dropout_min_samples:
            stuck[a - 1:b] = True
            out.append(("dropout", int(a - 1), int(b)))
    if x.size < 9:
        return sorted(out, key=lambda g: g[1])
    r = np.abs(_central(x))
    sigma = 1.4826 * np.median(r[2:-2][~stuck[2:-2]])  # |r| is folded: its median is the MAD
    if not sigma > 0:
        return sorted(out, key=lambda g: g[1])
    limit = spike_threshold * sigma
    hot = (r > limit) & ~stuck
    hot[:4] = hot[-4:] = False  # the cubic needs two samples each side of a window
    near = np.convolve(hot, np.ones(7), mode="same") > 0  # clusters: hot samples within 3
    bad = np.zeros(x.size, bool)
    for a, b in true_runs(near):
        a, b = max(a, 4), min(b, x.size - 4)
        # a few spikes make short clusters; a long hot run is signal (a fast chirp
        # against quiet rest portions) and would make the search combinatorial
        if 5 <= b - a <= 40:
            bad[_resolve(x, a, b, limit)] = True
    out += [("spike", int(a), int(b)) for a, b in true_runs(bad & ~stuck)]
    return sorted(out, key=lambda g: g[1])


def repair(x, glitches):
    """The record with the flagged samples replaced by a cubic spline through
    the good samples (held constant beyond the ends)."""
    x = np.array(x, dtype=float)
    bad = np.zeros(x.size, bool)
    for _, a, b in glitches:
        bad[a:b] = True
    good = np.flatnonzero(~bad)
    if bad.any() and good.size >= 4:
        i = np.flatnonzero(bad)
        inside = (i > good[0]) & (i < good[-1])
        x[i[inside]] = CubicSpline(good, x[good])(i[inside])
        x[i[~inside]] = np.interp(i[~inside], good, x[good])
    return x


def _detect_and_repair(x, spike_threshold, dropout_min_samples):
    """Glitches and the repaired record."""
    found = detect_glitches(x, spike_threshold, dropout_min_samples)
    return found, (repair(x, found) if found else np.asarray(x, dtype=float))


def screen_records(data, fs, remove=False, spike_threshold=SPIKE_THRESHOLD,
                   dropout_min_samples=DROPOUT_MIN_SAMPLES, t0=0.0):
    """Screen every channel for spikes and dropouts; optionally repair them.

    Parameters
    ----------
    data : dict
        channel name -> record (N,).
    fs : float
        Sampling frequency [Hz] (for the times in the report).
    remove : bool
        Replace flagged samples by interpolation (`repair`).
    spike_threshold, dropout_min_samples :
        See `detect_glitches`.
    t0 : float
        Time of sample 0 [s].

    Returns
    -------
    cleaned : dict
        Same keys; repaired records when ``remove``, else the input arrays.
    report : QualityReport
    """
    glitches, cleaned, n = [], {}, 0
    for name, x in data.items():
        found, fixed = _detect_and_repair(x, spike_threshold, dropout_min_samples)
        n = max(n, np.size(x))
        glitches += [Glitch(name, k, a, b, float(t0 + a / fs)) for k, a, b in found]
        cleaned[name] = fixed if remove and found else x
    settings = {"spike_threshold": spike_threshold, "dropout_min_samples": dropout_min_samples}
    return cleaned, QualityReport(tuple(glitches), n, bool(remove), settings)
