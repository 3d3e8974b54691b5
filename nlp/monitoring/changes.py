"""Change detection in a parameter history (structural health monitoring).

A parameter updated from every record of a monitoring campaign scatters for
three reasons: estimation noise (its standard error), environmental effects
(a temperature cycle, a slow drift) and damage (a step). A step is found by
comparing the median of the ``window`` records before a record with the median
of the ``window`` records from it on, against how much that comparison wanders
elsewhere in the same history.
"""

from dataclasses import dataclass

import numpy as np

__all__ = ["Change", "step_series", "detect_changes"]


@dataclass(frozen=True)
class Change:
    """A step in one parameter history.

    index : first record of the new level (0-based); before, after : medians
    of the segments either side [parameter unit]; z : step over its standard
    error (two window medians).
    """

    index: int
    before: float
    after: float
    z: float

    @property
    def relative(self):
        """(after - before) / before."""
        return (self.after - self.before) / self.before if self.before else float("nan")


def step_series(x, window):
    """D_j = median x[j:j+w] - median x[j-w:j] for every j; NaN where a window does not fit."""
    x = np.asarray(x, float)
    D = np.full(x.size, np.nan)
    for j in range(window, x.size - window + 1):
        D[j] = np.median(x[j:j + window]) - np.median(x[j - window:j])
    return D


def _refine(x, j, window):
    """The split in [j - w + 1, j + w - 1] with the least absolute deviation from the two
    segment medians (the window statistic can peak a record or two off the step)."""
    lo, hi = max(1, j - window + 1), min(x.size - 1, j + window - 1)
    a, b = max(0, j - window), min(x.size, j + window)
    cost = [np.abs(x[a:c] - np.median(x[a:c])).sum() + np.abs(x[c:b] - np.median(x[c:b])).sum()
            for c in range(lo, hi + 1)]
    return lo + int(np.argmin(cost))


def detect_changes(x, se=None, window=8, threshold=6.0, max_changes=3):
    """Steps in a parameter history.

    The step statistic D_j (:func:`step_series`) is compared with its own
    root-mean-square away from the steps already found: whatever makes the
    history wander without a step (estimation noise, a daily temperature cycle,
    a slow drift) makes D wander too, so the comparison calibrates itself. The
    scale is at least what the estimates' standard errors alone give,
    sqrt(pi / w) median(se). The strongest step is taken first, its
    neighbourhood (+-w records) set aside, and the search repeated.

    Parameters
    ----------
    x : (N,) array_like
        The parameter per record, in time order [its unit]; NaN for a record
        without a result (skipped).
    se : (N,) array_like, optional
        Standard error of each record's estimate [same unit].
    window : int
        Records on each side of a candidate step.
    threshold : float
        A step is reported when |D_j| exceeds this many times the scale.
    max_changes : int
        At most this many steps per parameter.

    Returns
    -------
    list of Change, in time order.
    """
    x = np.asarray(x, float)
    ok = np.isfinite(x)
    idx = np.flatnonzero(ok)
    xs = x[ok]
    D = step_series(xs, window)
    floor = 0.0
    if se is not None:
        s = np.asarray(se, float)[ok]
        s = s[np.isfinite(s)]
        if s.size:
            floor = float(np.sqrt(np.pi / window) * np.median(s))
    free = np.isfinite(D)
    steps = []
    while len(steps) < max_changes and free.any():
        j = int(np.flatnonzero(free)[np.argmax(np.abs(D[free]))])
        near = np.zeros_like(free)
        near[max(0, j - window):j + window + 1] = True
        rest = free & ~near
        for k, _ in steps:
            rest[max(0, k - window):k + window + 1] = False
        if rest.sum() < window:
            break
        scale = max(float(np.sqrt(np.mean(D[rest] ** 2))), floor)
        if scale <= 0 or abs(D[j]) < threshold * scale:
            break
        steps.append((_refine(xs, j, window), D[j] / scale))
        free &= ~near
    steps.sort()
    cuts = [0] + [j for j, _ in steps] + [xs.size]
    return [Change(index=int(idx[j]), before=float(np.median(xs[cuts[k]:j])),
                   after=float(np.median(xs[j:cuts[k + 2]])), z=float(z))
            for k, (j, z) in enumerate(steps)]
