"""Scatter search: many cheap trial points, a few local solves from the best.

Like MATLAB's GlobalSearch (the paper, Section 3.3.2) but built on the NLP
that is compiled once: trial points come from a scrambled Sobol sequence over
the box bounds (seeded), each is scored by one objective evaluation, and local
solves start from the best-scoring points that are mutually distant (so the
starts do not all fall into one basin). The case's initial point is always
start 0. Local solves run in worker processes; the answer depends only on the
seed, not on the number of workers or the order in which starts finish.
"""

from dataclasses import dataclass
import multiprocessing as mp
import os
import sys
import time

import numpy as np
from scipy.stats import qmc

__all__ = ["SearchConfig", "SearchResult", "trial_points", "pick_starts", "scatter_search"]


@dataclass(frozen=True)
class SearchConfig:
    """starts: local solves; trial_factor: trial points per start; seed; workers;
    min_distance: minimum distance between starts in the unit box (0..sqrt(n))."""

    starts: int = 20
    trial_factor: int = 10
    seed: int = 0
    workers: int = 1
    min_distance: float = 0.1


@dataclass
class SearchResult:
    """All finished local solves, the best one and a summary of agreement."""

    results: list
    best: object
    n_trial: int
    n_requested: int
    interrupted: bool
    seconds: float
    rel_tol: float = 0.01

    @property
    def near_best(self):
        """Local results whose objective is within rel_tol (1 %) of the best."""
        fb = self.best.f
        return [r for r in self.results if r.f <= fb + self.rel_tol * abs(fb) + 1e-300]

    def spread(self, to_theta):
        """Min, max and std of each theta over the near-best starts."""
        T = np.array([to_theta(r.z) for r in self.near_best])
        return {"min": T.min(axis=0), "max": T.max(axis=0), "std": T.std(axis=0)}


def trial_points(lo, hi, n, seed):
    """n scrambled-Sobol points in the box [lo, hi] (rows)."""
    sampler = qmc.Sobol(d=lo.size, scramble=True, seed=seed)
    m = int(np.ceil(np.log2(max(n, 2))))
    U = sampler.random_base2(m)[:n]
    return lo + U * (hi - lo)


def pick_starts(Z, scores, n, lo, hi, min_distance):
    """Indices of the best-scoring rows of Z, each at least min_distance apart
    (in box-normalised coordinates); fills up with the next best if needed."""
    U = (Z - lo) / np.where(hi > lo, hi - lo, 1.0)
    order = np.argsort(np.where(np.isfinite(scores), scores, np.inf), kind="stable")
    chosen = []
    for i in order:
        if len(chosen) == n:
            break
        if not np.isfinite(scores[i]):
            break
        if all(np.linalg.norm(U[i] - U[j]) >= min_distance for j in chosen):
            chosen.append(i)
    for i in order:  # not enough distant points: take the next best
        if len(chosen) == n:
            break
        if i not in chosen:
            chosen.append(i)
    return np.array(chosen, dtype=int)


_PROBLEM = None  # set in the parent before forking the workers


def _solve_start(item):
    i, z0 = item
    return i, _PROBLEM.solve(z0)


def _progress(done, total, best_f, stream):
    if stream is None:
        return
    width = 30
    filled = int(width * done / max(total, 1))
    bar = "#" * filled + "." * (width - filled)
    end = "\n" if done == total else ""
    stream.write(f"\r  local solves [{bar}] {done}/{total}  best f = {best_f:.4g}{end}")
    stream.flush()


def scatter_search(problem, config=SearchConfig(), progress=None):
    """Run the scatter search on an :class:`nlp.problem.UpdatingProblem`.

    progress : a text stream for a progress bar (default: stderr when it is a
    terminal). Ctrl-C stops the search and returns the starts that finished
    (``interrupted=True``).
    """
    global _PROBLEM
    if progress is None:
        progress = sys.stderr if sys.stderr.isatty() else None
    t0 = time.perf_counter()
    lo, hi = problem.bounds
    n_starts = max(1, int(config.starts))
    starts = [np.clip(problem.z0, lo, hi)]
    n_trial = 0
    if n_starts > 1:
        n_trial = max(n_starts - 1, config.trial_factor * n_starts)
        Z = trial_points(lo, hi, n_trial, config.seed)
        with np.errstate(all="ignore"):
            scores = problem.objective_batch(Z.T)
        idx = pick_starts(Z, scores, n_starts - 1, lo, hi, config.min_distance)
        starts += [Z[i] for i in idx]
    items = list(enumerate(starts))
    results = {}
    best_f = np.inf
    interrupted = False
    _PROBLEM = problem
    workers = max(1, min(int(config.workers), len(items)))
    pool = None
    try:
        if workers == 1:
            iterator = map(_solve_start, items)
        else:
            ctx = mp.get_context("fork")
            pool = ctx.Pool(workers)
            iterator = pool.imap_unordered(_solve_start, items, chunksize=max(1, len(items) // (8 * workers)))
        for i, res in iterator:
            results[i] = res
            best_f = min(best_f, res.f)
            _progress(len(results), len(items), best_f, progress)
    except KeyboardInterrupt:
        interrupted = True
        if progress is not None:
            progress.write(f"\n  interrupted: keeping {len(results)} finished starts\n")
    finally:
        if pool is not None:
            pool.terminate()
            pool.join()
        _PROBLEM = None
    if not results:
        raise KeyboardInterrupt("interrupted before any local solve finished")
    ordered = [results[i] for i in sorted(results)]
    # The lowest objective wins even if its solver stopped on an iteration limit:
    # every f is a true evaluation at a point inside the bounds, and a slow
    # crawl along a weakly identified valley must not lose to a worse "success".
    finite = [r for r in ordered if np.isfinite(r.f)] or ordered
    best = min(finite, key=lambda r: r.f)  # min keeps the lowest start index on ties
    return SearchResult(results=ordered, best=best, n_trial=n_trial, n_requested=len(items),
                        interrupted=interrupted, seconds=time.perf_counter() - t0)


def default_workers():
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        return os.cpu_count() or 1
