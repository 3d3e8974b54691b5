"""Scatter-search scaling on the 4-DOF case: executors, 10,000 starts, pick_starts.

    python scripts/bench_search.py [--case PATH] [--workers 2] [--only pool|big|pick]

Prints, on this machine:
1. 1,000 starts with the local process pool and with a Dask LocalCluster of the
   same number of single-threaded workers (cluster start-up timed separately):
   wall and CPU seconds of each run (all processes: this one, which hosts the
   scheduler, and the workers), the Dask/local ratios, and whether both found
   the same best. On a shared machine the CPU ratio is the steadier measure;
2. 10,000 starts with the local pool: trial scoring + picking + local solves
   (screened, the best polished: README "Scatter search"): the wall time, the CPU seconds of all processes (divided by the cores: the
   wall time the run needs on cores it does not share), converged starts and the
   best objective;
3. pick_starts at 1,000, 3,000 and 10,000 starts (10 trial points per start, 17
   dimensions); tests/test_search_reliability.py checks its picks against the
   point-by-point rule it replaces.
The machine's load average is printed with each figure: the machine is shared.
"""

import argparse
import os
import time

import numpy as np

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.solve.executors import Setup, make_executor
from nlp.solve.search import SearchConfig, pick_starts, scatter_search
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))


def _load():
    return "load average %.1f" % os.getloadavg()[0]


def _search(problem, setup, ex, starts, seed=0):
    cfg = SearchConfig(starts=starts, seed=seed, workers=ex.workers)
    t0 = time.perf_counter()
    res = scatter_search(problem, cfg, progress=None, executor=ex, setup=setup)
    return time.perf_counter() - t0, res


def bench_pool(problem, setup, workers, starts=1000):
    print(f"1. {starts} starts, {workers} workers: local process pool vs Dask LocalCluster")
    t0 = time.perf_counter()
    dask = make_executor("dask", workers=workers)
    print(f"   Dask LocalCluster start-up {time.perf_counter() - t0:.1f} s ({_load()})")
    local = make_executor("local", workers=workers)
    wall = {"local": [], "dask": []}
    cpu = {"local": [], "dask": []}
    best = {}
    try:
        for rep in range(2):  # alternate, so both see the same load; keep the faster of two
            for name, ex in (("local", local), ("dask", dask)):
                c0 = _cpu(ex)
                dt, res = _search(problem, setup, ex, starts)
                wall[name].append(dt)
                cpu[name].append(_cpu(ex) - c0)
                best[name] = res.best.f
                print(f"   {name:5s} run {rep + 1}: wall {dt:6.2f} s, CPU {cpu[name][-1]:6.2f} s, "
                      f"{len(res.results)} starts, best f {res.best.f:.10g} ({_load()})")
    finally:
        dask.close()
    tl, td = min(wall["local"]), min(wall["dask"])
    cl, cd = min(cpu["local"]), min(cpu["dask"])
    print(f"   wall: local {tl:.2f} s, Dask {td:.2f} s, Dask/local = {td / tl:.3f}")
    print(f"   CPU:  local {cl:.2f} s, Dask {cd:.2f} s, Dask/local = {cd / cl:.3f} "
          f"(overhead {100 * (cd / cl - 1):+.1f} %); same best: {best['local'] == best['dask']}")


def bench_big(problem, setup, workers, starts=10_000):
    print(f"2. {starts} starts of the 4-DOF case, local pool, {workers} workers")
    cpu0 = _cpu()
    with make_executor("local", workers=workers) as ex:
        dt, res = _search(problem, setup, ex, starts)
    cpu = _cpu() - cpu0  # this process and its (joined) worker processes
    conv = sum(r.success for r in res.results)
    print(f"   wall {dt:.1f} s for {len(res.results)} starts ({res.n_trial} trial points), "
          f"{conv} converged, best f {res.best.f:.10g} ({_load()})")
    print(f"   screened at IPOPT tol 1e-5, {len(res.polished)} lowest polished at 1e-8; "
          f"best: {res.best.status}, {res.best.iterations} iterations in all")
    print(f"   CPU {cpu:.1f} s in all processes ({1000 * cpu / len(res.results):.1f} ms per start): "
          f"{cpu / workers:.1f} s of wall time on {workers} cores that are not shared")


def _cpu(ex=None):
    """CPU seconds of this process, its reaped children (forked local workers) and,
    for a Dask executor, its worker processes (the scheduler runs in this process)."""
    import resource
    own, kids = (resource.getrusage(w) for w in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    total = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    if ex is not None and ex.kind == "dask":
        total += sum(ex._client.run(_worker_cpu).values())
    return total


def _worker_cpu():
    import psutil
    t = psutil.Process().cpu_times()
    return t.user + t.system


def bench_pick():
    print("3. pick_starts (17 dimensions, 10 trial points per start, min distance 0.1)")
    rng = np.random.default_rng(0)
    lo, hi = np.zeros(17), np.ones(17)
    for starts in (1_000, 3_000, 10_000):
        Z, scores = rng.random((10 * starts, 17)), rng.random(10 * starts)
        t0 = time.perf_counter()
        idx = pick_starts(Z, scores, starts - 1, lo, hi, 0.1)
        print(f"   {starts} starts: {time.perf_counter() - t0:.2f} s, {len(set(idx.tolist()))} "
              f"distinct picks ({_load()})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default=os.path.join(HERE, "..", "cases", "four_story_shear_frame",
                                                   "case.yaml"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--only", choices=("pool", "big", "pick"))
    a = ap.parse_args()
    print(f"{os.cpu_count()} CPUs, {_load()}")
    if a.only in (None, "pick"):
        bench_pick()
    if a.only == "pick":
        return
    case = assemble(load_case(a.case))
    problem = build_problem(case)
    setup = Setup(build_problem, case, value=problem)
    if a.only in (None, "pool"):
        bench_pool(problem, setup, a.workers)
    if a.only in (None, "big"):
        bench_big(problem, setup, a.workers)


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
