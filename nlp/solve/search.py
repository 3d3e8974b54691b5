"""Scatter search: many cheap trial points, a few local solves from the best.

Like MATLAB's GlobalSearch (the paper, Section 3.3.2) but built on the NLP
that is compiled once: trial points come from a scrambled Sobol sequence over
the box bounds (seeded), each is scored by one objective evaluation, and local
solves start from the best-scoring points that are mutually distant (so the
starts do not all fall into one basin). The case's initial point is always
start 0.

Local solves run on an executor (:mod:`nlp.solve.executors`); each start's result
comes back as soon as it finishes and is appended to the checkpoint
(:mod:`nlp.solve.checkpoint`). Only converged solves compete for the best (IPOPT
``Solve_Succeeded`` or ``Solved_To_Acceptable_Level``, sqpmethod success, with
a finite objective and point); the lowest objective wins, ties go to the
lowest start index, so the answer depends only on the seed, not on the
executor, the number of workers or the order in which starts finish.

Starts are screened at a looser IPOPT tolerance when the case leaves it to us
(:data:`nlp.solve.stopping.SCREEN_TOL`); the ``POLISH`` lowest converged starts are then
re-solved at the full tolerance before the best is chosen.
"""

from collections import Counter
from dataclasses import dataclass, fields, replace
import os
import time

import numpy as np
from scipy.spatial.distance import cdist
from scipy.stats import qmc

from nlp.errors import SearchFailed
from nlp.output.progress import note, stage
from nlp.solve.executors import Setup, interrupts_as_keyboard, make_executor
from nlp.solve.problem import LocalResult
from nlp.solve.stopping import LIMIT_STATUSES

__all__ = ["SearchSettings", "SearchConfig", "SearchResult", "trial_points", "pick_starts", "scatter_search",
           "start_points", "converged", "solve_start", "default_workers"]

IPOPT_CONVERGED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")


@dataclass(frozen=True)
class SearchSettings:
    """The settings a case file's search section and a scatter search share."""

    starts: int = 20                       # local solves of the scatter search
    trial_factor: int = 10                 # trial points per start
    seed: int = 0                          # seed of the trial points
    workers: int = 1                       # worker processes
    executor: str = "local"      # where local solves run (nlp.solve.executors): local | dask | serial
    scheduler: str = None        # Dask scheduler address, e.g. tcp://10.0.0.5:8786


@dataclass(frozen=True)
class SearchConfig(SearchSettings):
    """The shared :class:`SearchSettings` and min_distance: minimum distance between
    starts in the unit box (0..sqrt(n))."""

    min_distance: float = 0.1

    @classmethod
    def of(cls, settings, **changes):
        """The search config of any SearchSettings (a case's search section), with changes."""
        shared = {f.name: getattr(settings, f.name) for f in fields(SearchSettings)}
        return cls(**{**shared, **changes})


@dataclass
class SearchResult:
    """The finished local solves (ordered by start index), the best converged one
    and a summary of agreement."""

    results: list
    best: object
    n_trial: int
    n_requested: int
    interrupted: bool
    seconds: float
    rel_tol: float = 0.01
    indices: list = None
    resumed: int = 0
    agreed: tuple = ()
    polished: tuple = ()  # starts re-solved at the full tolerance after screening


    def __post_init__(self):
        if self.indices is None:
            self.indices = list(range(len(self.results)))

    @property
    def near_best(self):
        """Converged results whose objective is within rel_tol (1 %) of the best."""
        fb = self.best.f
        ok = set(self.agreed)
        return [r for i, r in zip(self.indices, self.results)
                if (r.success or i in ok) and r.f <= fb + self.rel_tol * abs(fb) + 1e-300]

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


def _too_close(U, cand, chosen, d):
    """For each row of U[cand]: is it closer than d to any row of U[chosen]?"""
    close = np.zeros(len(cand), dtype=bool)
    for k in range(0, len(chosen), 4096):  # bounded memory: len(cand) x 4096 distances
        close |= cdist(U[cand], U[chosen[k:k + 4096]]).min(axis=1) < d
    return close


def pick_starts(Z, scores, n, lo, hi, min_distance):
    """Indices of the best-scoring rows of Z, each at least min_distance apart
    (in box-normalised coordinates); fills up with the next best if needed.

    Greedy in score order, as one would write it point by point, but done in
    blocks: a block of the next-best candidates is first screened against all
    starts chosen so far (one distance matrix), then the survivors are taken in
    order against each other. The picks are those of the point-by-point rule.
    """
    U = (Z - lo) / np.where(hi > lo, hi - lo, 1.0)
    s = np.where(np.isfinite(scores), scores, np.inf)
    order = np.argsort(s, kind="stable")
    ranked = order[np.isfinite(s[order])]
    chosen = np.empty(0, dtype=int)
    pos = 0
    while len(chosen) < n and pos < len(ranked):
        block = ranked[pos:pos + int(np.clip(n - len(chosen), 256, 2048))]
        pos += len(block)
        if len(chosen):
            block = block[~_too_close(U, block, chosen, min_distance)]
        D = cdist(U[block], U[block])
        alive = np.ones(len(block), dtype=bool)
        take = []
        for j in range(len(block)):
            if len(chosen) + len(take) == n:
                break
            if alive[j]:
                take.append(j)
                alive[j + 1:] &= D[j, j + 1:] >= min_distance
        chosen = np.concatenate([chosen, block[take]])
    if len(chosen) < n:  # not enough distant points: take the next best
        rest = order[~np.isin(order, chosen)]
        chosen = np.concatenate([chosen, rest[:n - len(chosen)]])
    return chosen.astype(int)


def start_points(problem, config, executor=None, setup=None):
    """The start points (rows) and the number of trial points scored.

    Start 0 is the case's initial point; the others are picked from the
    seeded trial points, so the same problem and seed give the same starts.
    With an executor of several workers the trial points are scored there, in
    equal chunks (each point's score does not depend on the chunking).
    """
    lo, hi = problem.bounds
    n_starts = max(1, int(config.starts))
    starts = [np.clip(problem.z0, lo, hi)]
    n_trial = 0
    if n_starts > 1:
        n_trial = max(n_starts - 1, config.trial_factor * n_starts)
        Z = trial_points(lo, hi, n_trial, config.seed)
        if executor is not None and executor.workers > 1 and n_trial >= _PARALLEL_SCORING:
            size = -(-n_trial // (4 * executor.workers))
            chunks = [(k, Z[k:k + size]) for k in range(0, n_trial, size)]
            got = executor.map(setup or Setup(value=problem), _score_chunk, chunks, batch_size=1)
            scores = np.concatenate([got[k] for k, _ in chunks])
        else:
            scores = _score_chunk(problem, Z)
        idx = pick_starts(Z, scores, n_starts - 1, lo, hi, config.min_distance)
        starts += [Z[i] for i in idx]
    return np.array(starts), n_trial


_PARALLEL_SCORING = 20_000  # trial points; below this, shipping them costs more than it saves


_SCORE_BLOCK = 128  # points per compiled call: larger blocks cost 2-3x the CPU (memory traffic)


def _score_chunk(problem, Z):
    # Each point's score is computed on its own, so the blocking does not change it;
    # small blocks keep the map's work arrays in cache (blocks of 12,500 points spent
    # half their time in the kernel, faulting in fresh memory).
    with np.errstate(all="ignore"):
        return np.concatenate([problem.objective_batch(Z[k:k + _SCORE_BLOCK].T)
                               for k in range(0, len(Z), _SCORE_BLOCK)] or [np.empty(0)])


def converged(problem, res):
    """Did a local solve converge to a finite point (the only ones that may win)?"""
    if not (np.isfinite(res.f) and np.all(np.isfinite(res.z))):
        return False
    if problem.solver_config.name == "ipopt":
        # IPOPT's own tests, or a point UpdatingProblem.solve found stationary where IPOPT's
        # absolute tolerance cannot be met (Gauss-Newton decrement, or Newton steps)
        return res.status in IPOPT_CONVERGED or (bool(res.success)
                                                 and res.status.startswith("Stationary"))
    return bool(res.success)


def solve_start(problem, z0, screen=False, prefit=True):
    """One local solve that never raises: a failure is a result with f = inf.

    screen: use the problem's screening tolerance when it has one
    (:meth:`nlp.solve.problem.UpdatingProblem.solve`); prefit: False for a re-solve
    from an optimum of the problem's own residual.

    ``success`` of the returned result means :func:`converged`. A solve that
    stopped without converging keeps the objective evaluated at the point it
    returned (inf when that is not finite), never the solver's own report.
    """
    t0 = time.perf_counter()
    try:
        res = problem.solve(z0, screen=screen, prefit=prefit)
    except Exception as exc:  # a failed start must not end the search
        msg = " ".join(str(exc).split())[:200]
        return LocalResult(z=np.asarray(z0, float), f=np.inf, success=False,
                           status=f"error: {type(exc).__name__}: {msg}", iterations=0,
                           seconds=time.perf_counter() - t0, z0=np.asarray(z0, float))
    ok = converged(problem, res)
    f = res.f if np.isfinite(res.f) and np.all(np.isfinite(res.z)) else np.inf
    if not ok and np.isfinite(f):
        # a solver that gave up may report anything (IPOPT: f = 0 after an invalid
        # number); keep only a true evaluation at the point it returned
        with np.errstate(all="ignore"):
            f = problem.objective(res.z)
    return replace(res, success=ok, f=float(f) if np.isfinite(f) else np.inf)


def _solve_item(problem, item):
    return solve_start(problem, item, screen=True)


POLISH = 10  # screened starts re-solved at the full tolerance: the lowest converged ones


def _polish(problem, results, show=True):
    """Re-solve the POLISH lowest converged screened starts with the full tolerance,
    from where screening stopped; returns their start indices.

    Screening (IPOPT tol 1e-5 instead of 1e-8) saves a fifth of the iterations of
    every start; only the candidates for the best need the last digits. A polish
    that does not converge leaves the screened result (converged at 1e-5) in place;
    a screened result already stationary (:meth:`UpdatingProblem.solve`) is kept.
    """
    if not getattr(problem, "can_screen", False):
        return ()
    top = sorted((r.f, i) for i, r in results.items() if r.success)[:POLISH]
    with stage("polishing", total=len(top), unit="start", show=show) as bar:
        for _, i in top:
            _polish_one(problem, results, i)
            bar.update()
            bar.note(_start_line("polished start", i, results[i]))
    return tuple(sorted(i for _, i in top))


def _polish_one(problem, results, i):
    """Re-solve start i at the full tolerance unless its screened result is stationary."""
    if str(results[i].status).startswith("Stationary"):
        # stationary by the Newton test at the screening stop: a full-tolerance
        # IPOPT re-solve only creeps to its iteration limit again (measured on a blind
        # 5-storey null case: re-solving them, the diagnosis had finished only its
        # first round of refits after 7.5 min; skipping them, all of it took 7 min 41 s)
        return
    r = results[i]
    p = solve_start(problem, r.z, prefit=False)
    if p.success:
        results[i] = replace(p, z0=r.z0, iterations=r.iterations + p.iterations,
                             seconds=r.seconds + p.seconds)


def _start_line(what, i, res):
    """One start's line on a terminal: iterations, objective, seconds, solver status."""
    pre = f" (after {res.prefit_iterations} of the prefit)" if res.prefit_iterations else ""
    return (f"  {what} {i}: {res.iterations} iterations{pre}, f = {res.f:.6g}, "
            f"{res.seconds:.2f} s, {res.status}")


def _failure_summary(results):
    counts = Counter(r.status for r in results)
    return ", ".join(f"{n} {s}" for s, n in counts.most_common(5))


def scatter_search(problem, config=SearchConfig(), progress=None, executor=None, setup=None,
                   checkpoint=None):
    """Run the scatter search on an :class:`nlp.solve.problem.UpdatingProblem`.

    Parameters
    ----------
    progress : None (default) shows the starts and the polishing on stderr when it is a
        terminal (:mod:`nlp.output.progress`); False never does.
    executor : an :class:`nlp.solve.executors.Executor`; default: one made from
        ``config`` (executor, workers, scheduler) and closed at the end.
    setup : an :class:`nlp.solve.executors.Setup` that rebuilds ``problem`` in another
        process (needed by Dask; forked local workers inherit ``problem``).
    checkpoint : an :class:`nlp.solve.checkpoint.Checkpoint`; every finished start is
        appended to it, and the starts it already holds (``resume``) are not
        solved again.

    SIGINT and SIGTERM stop the search within a second or two and return the
    starts that finished (``interrupted=True``); KeyboardInterrupt is raised
    only when none of them converged. :class:`nlp.errors.SearchFailed` is
    raised when the search finished and no start converged.
    """
    progress = progress is not False
    t0 = time.perf_counter()
    setup = setup or Setup(value=problem)
    with interrupts_as_keyboard() as guard:
        run = _solve_starts(problem, config, executor, setup, checkpoint, progress, guard)
        with guard.deferred(swallow=True):  # a few solves; a Ctrl-C now waits for them
            polished = _polish(problem, run.results, progress)
    results = run.results
    indices = sorted(results)
    ordered = [results[i] for i in indices]
    agreed, best = _best(problem, results, indices, ordered, run.interrupted)
    return SearchResult(results=ordered, best=best, n_trial=run.n_trial,
                        n_requested=run.n_requested, interrupted=run.interrupted,
                        seconds=time.perf_counter() - t0, indices=indices, resumed=run.resumed,
                        agreed=tuple(agreed), polished=polished)


@dataclass
class _StartsRun:
    """The local solves of one search: {start index: LocalResult} and how they ran."""

    results: dict
    n_trial: int
    n_requested: int
    resumed: int
    interrupted: bool


def _solve_starts(problem, config, executor, setup, checkpoint, progress, guard):
    """Solve the search's starts on the executor (one made from ``config`` when None),
    recording each in the checkpoint; a KeyboardInterrupt keeps the finished ones."""
    own = executor is None
    interrupted = False
    stream = None
    results = {}
    try:
        if own:
            executor = make_executor(config.executor, config.workers, config.scheduler)
        starts, n_trial = start_points(problem, config, executor, setup)
        if checkpoint is not None:
            results = checkpoint.open(problem, config, starts)
        resumed = len(results)
        todo = [(i, starts[i]) for i in range(len(starts)) if i not in results]
        stream = executor.stream(setup, _solve_item, todo)
        with stage("local solves", total=len(starts), unit="start", initial=resumed,
                   show=progress) as bar:
            _collect(stream, results, checkpoint, guard, bar)
    except KeyboardInterrupt:
        if stream is None:  # nothing was started: nothing to keep
            raise
        interrupted = True
        with guard.deferred(swallow=True):
            for i, res in stream.stop():
                results.setdefault(i, res)
                if checkpoint is not None:
                    checkpoint.append(i, res)
            note(f"  interrupted: keeping {len(results)} finished starts", progress)
    finally:
        with guard.deferred(swallow=True):
            if stream is not None:
                stream.close()
            if own and executor is not None:
                executor.close()
            if checkpoint is not None:
                checkpoint.close()
    return _StartsRun(results, n_trial, len(starts), resumed, interrupted)


def _collect(stream, results, checkpoint, guard, bar):
    """Record each start as it arrives (results, checkpoint) and show it on the bar."""
    best_f = min([r.f for r in results.values() if r.success] or [np.inf])
    for i, res in stream:
        with guard.deferred():  # a received start is always recorded
            results[i] = res
            if checkpoint is not None:
                checkpoint.append(i, res)
            if res.success:
                best_f = min(best_f, res.f)
            bar.update(best_f=f"{best_f:.4g}")
            bar.note(_start_line("start", i, res))


def _best(problem, results, indices, ordered, interrupted):
    """(agreed starts, best result): the lowest converged objective, or the minimum that
    starts stopped at a limit agree on (:func:`agreed_minimum`); ties to the lowest index."""
    good = [(r.f, i) for i, r in zip(indices, ordered) if r.success]
    dof = getattr(problem, "n_used", 0) - len(problem.z0)
    agreed = agreed_minimum(ordered, indices, rel=AGREE_CHI2 / max(dof, 1))
    if agreed:
        good = [(results[i].f, i) for i in agreed]
    if not good:
        if interrupted:
            raise KeyboardInterrupt("interrupted before any local solve converged")
        raise SearchFailed(f"none of the {len(ordered)} local solves converged "
                           f"({_failure_summary(ordered)})")
    return agreed, results[min(good)[1]]  # lowest f; the lowest start index on ties


AGREE_CHI2 = 0.1  # objectives closer than this in chi-square are one minimum
AGREE_MIN = 3     # independent starts that must reach it


def agreed_minimum(results, indices, rel=1e-4, n_min=AGREE_MIN):
    """Starts that stopped at a solver limit below every converged objective, when
    at least ``n_min`` independent starts agree on that objective within ``rel``.

    The search uses rel = 0.1 / (residuals - parameters): with the noise
    variance estimated from the fit, s^2 = 2 f / dof, objectives that differ by
    rel f differ by 0.1 in chi-square, far below what the data can tell apart.

    A weakly identified direction (a damping entry the data barely see) can make
    IPOPT crawl until its iteration limit while the objective no longer moves:
    then no start meets the tolerance, and a start that "converged" elsewhere
    may sit far higher. Agreement of independent starts is the check that the
    objective's minimum is reached (not the parameters along the weak
    direction; the result flags that). Returns the indices of the agreeing
    starts (converged ones included), or [] when the converged best stands.
    """
    f_conv = min([r.f for r in results if r.success] or [np.inf])
    stopped = [r.f for r in results
               if not r.success and r.status in LIMIT_STATUSES and np.isfinite(r.f)]
    if not stopped:
        return []
    f_low = min(stopped)
    if not f_low < f_conv - rel * abs(f_conv):
        return []
    group = [i for i, r in zip(indices, results) if np.isfinite(r.f)
             and (r.success or r.status in LIMIT_STATUSES) and r.f <= f_low + rel * abs(f_low)]
    return group if len(group) >= n_min else []


def default_workers():
    """Cores available to this process."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        return os.cpu_count() or 1
