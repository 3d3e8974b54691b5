"""Benchmark the core updater against a plain scipy baseline on one case.

Measured (wall time, ``time.perf_counter``), on the same start points for every method
(the case's initial point z0 plus uniform perturbations of +-20 % of each bound's width,
clipped to the bounds, from ``np.random.default_rng(seed)``):

1. CasADi/IPOPT local solves (the package): problem build time (cold = empty compile
   cache, so gcc runs; warm = cached library), median solve time, median iterations,
   success rate, and the max relative mass / stiffness error against truth.json at the
   best solution (lowest objective) of the runs.
2. The same with CasADi's sqpmethod.
3. A baseline "a Python user would write": scipy.optimize.least_squares (trf, same
   bounds, finite-difference Jacobian, ftol = xtol = gtol = 1e-10) on a numpy residual
   log|H_a| - log|H_x| (weighted, used points only), the package's default residual.
4. The speed-up (scipy median / IPOPT median).
5. A scatter search with --starts local solves (IPOPT, 2 workers; its own Sobol-picked
   starts) and the scipy baseline from those same starts on 2 processes. The baseline
   runs only if the local median predicts < 5 min (and is cut at 5 min, then
   extrapolated from its rate); otherwise it is extrapolated from the local median.
   Every extrapolated figure is labelled "estimated".

Run:  python scripts/bench_core.py [--case PATH] [--n-local 20] [--starts 1000] [--seed 0]
      [--quick]    (--quick: 5 local solves, 50 starts; a smoke run of ~15 s)
The full run takes ~3.5 min on 2 cores, mostly the scipy multi-start.
"""

import argparse
import json
import multiprocessing as mp
import os
import tempfile
import time

import numpy as np
from scipy.optimize import least_squares

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.frf.reference import channel_frfs
from nlp.solve.problem import LocalResult
from nlp.solve.search import SearchConfig, scatter_search
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_CASE = os.path.join(HERE, "..", "cases", "four_story_shear_frame", "case.yaml")
WORKERS = 2
SCIPY_LIMIT = 300.0  # s: time budget of the scipy multi-start


def start_points(problem, n, seed):
    """z0 plus n-1 uniform perturbations within +-20 % of the bounds' width, clipped."""
    lo, hi = problem.bounds
    z0 = np.clip(problem.z0, lo, hi)
    dz = np.random.default_rng(seed).uniform(-0.2, 0.2, (n - 1, z0.size)) * (hi - lo)
    return [z0] + list(np.clip(z0 + dz, lo, hi))


def build_timed(path, overrides):
    """(case, problem, cold build s, warm build s); cold = empty compile cache (gcc runs)."""
    case = assemble(load_case(path, overrides))
    old = os.environ.get("FRF_NLP_CACHE")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["FRF_NLP_CACHE"] = tmp
        t0 = time.perf_counter()
        build_problem(case)
        cold = time.perf_counter() - t0
    if old is None:
        del os.environ["FRF_NLP_CACHE"]
    else:
        os.environ["FRF_NLP_CACHE"] = old
    build_problem(case)  # make sure the normal cache holds the library
    t0 = time.perf_counter()
    problem = build_problem(case)
    return case, problem, cold, time.perf_counter() - t0


def numpy_residual(case):
    """r(z) = w (log|H_a| - log|H_x|) over used points, numpy only."""
    T, c = case.params.T, case.params.c
    sa, sb, sd = case.params.slices()
    tg = case.target
    used = tg.weight > 0
    log_hx = np.log(np.abs(tg.H[used]))
    w = tg.weight[used]

    def residual(z):
        theta = T @ z + c
        M, K = case.model.matrices(theta[sa], theta[sb])
        C = case.damping.matrix(theta[sd], M, K)
        H = channel_frfs(M, C, K, tg.omega, tg.channels, tg.excitation, tg.force_dof)
        return w * (np.log(np.abs(H[used])) - log_hx)
    return residual


def scipy_solve(residual, z0, bounds):
    """One least_squares run, reported as a LocalResult (iterations = nfev)."""
    t0 = time.perf_counter()
    r = least_squares(residual, z0, bounds=bounds, method="trf", ftol=1e-10, xtol=1e-10,
                      gtol=1e-10)
    return LocalResult(z=r.x, f=float(r.cost), success=bool(r.success), status=r.message,
                       iterations=int(r.nfev), seconds=time.perf_counter() - t0, z0=z0)


_JOB = None  # (residual, bounds) for forked scipy workers


def _scipy_job(z0):
    return scipy_solve(_JOB[0], z0, _JOB[1])


def scipy_multistart(residual, starts, bounds):
    """Run all starts on WORKERS processes; stop at SCIPY_LIMIT s. Returns (results, s)."""
    global _JOB
    _JOB = (residual, bounds)
    results, t0 = [], time.perf_counter()
    with mp.get_context("fork").Pool(WORKERS) as pool:
        for r in pool.imap_unordered(_scipy_job, starts):
            results.append(r)
            if time.perf_counter() - t0 > SCIPY_LIMIT:
                break
    return results, time.perf_counter() - t0


def scipy_multistart_row(residual, search, t_median, case, problem, truth):
    """Table row for the scipy baseline from the scatter search's starts."""
    starts = [r.z0 for r in search.results]
    estimate = t_median * len(starts) / WORKERS
    if estimate >= SCIPY_LIMIT:
        return ["scipy least_squares (estimated: median x starts / 2)", f"~{estimate:.0f}",
                "-", "-", "-", "-"]
    results, sec = scipy_multistart(residual, starts, problem.bounds)
    if len(results) < len(starts):
        return [f"scipy least_squares (estimated; {len(results)} done in 5 min)",
                f"~{sec * len(starts) / len(results):.0f}", *quality(results, case, problem, truth)]
    return ["scipy least_squares, same starts", f"{sec:.1f}", *quality(results, case, problem, truth)]


def quality(results, case, problem, truth):
    """Cells: starts within 1 % of the best objective, best f, max relative mass and
    stiffness errors vs truth at the best successful result."""
    best = min([r for r in results if r.success] or results, key=lambda r: r.f)
    near = sum(r.f <= best.f * 1.01 + 1e-300 for r in results)
    theta = problem.theta(best.z)
    sa, sb, _ = case.params.slices()
    em = np.max(np.abs(case.model.beta_nominal * (1 + theta[sb]) / truth["masses"] - 1))
    ek = np.max(np.abs(case.model.alpha_nominal * (1 + theta[sa]) / truth["stiffnesses"] - 1))
    return [f"{near}/{len(results)}", f"{best.f:.6g}", f"{em * 100:.2f} %", f"{ek * 100:.2f} %"]


def local_row(name, case, problem, results, truth, build, unit="iter"):
    t = np.median([r.seconds for r in results]) * 1e3
    its = np.median([r.iterations for r in results])
    ok = np.mean([r.success for r in results]) * 100
    return [name, build, f"{t:.1f}", f"{its:.0f} {unit}", f"{ok:.0f} %",
            *quality(results, case, problem, truth)]


def table(header, rows):
    widths = [max(len(str(x)) for x in col) for col in zip(header, *rows)]
    line = lambda row: "  ".join(str(x).ljust(w) if i == 0 else str(x).rjust(w)
                                 for i, (x, w) in enumerate(zip(row, widths)))
    rule = "-" * len(line(header))
    return "\n".join([line(header), rule] + [line(r) for r in rows])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default=DEFAULT_CASE)
    ap.add_argument("--n-local", type=int, default=20)
    ap.add_argument("--starts", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="5 local solves, 50 starts")
    a = ap.parse_args()
    n_local, n_starts = (5, 50) if a.quick else (a.n_local, a.starts)
    path = os.path.abspath(a.case)
    with open(os.path.join(os.path.dirname(path), "truth.json")) as fh:
        truth = {k: np.asarray(v) for k, v in json.load(fh).items() if k in ("masses", "stiffnesses")}

    case, ipopt, cold_i, warm_i = build_timed(path, {})
    _, sqp, cold_s, warm_s = build_timed(path, {"solver": "sqpmethod"})
    starts = start_points(ipopt, n_local, a.seed)
    residual = numpy_residual(case)
    z0 = starts[0]
    f_np, f_ca = 0.5 * np.sum(residual(z0) ** 2), ipopt.objective(z0)

    res_i = [ipopt.solve(z) for z in starts]
    res_s = [sqp.solve(z) for z in starts]
    res_p = [scipy_solve(residual, z, ipopt.bounds) for z in starts]

    header = ["method", "build cold/warm [s]", "median [ms]", "median work", "success",
              "within 1 %", "best f", "max mass err", "max stiff err"]
    rows = [local_row("CasADi ipopt", case, ipopt, res_i, truth, f"{cold_i:.2f}/{warm_i:.3f}"),
            local_row("CasADi sqpmethod", case, sqp, res_s, truth, f"{cold_s:.2f}/{warm_s:.3f}"),
            local_row("scipy least_squares", case, ipopt, res_p, truth, "-", unit="nfev")]
    t_i = np.median([r.seconds for r in res_i])
    t_p = np.median([r.seconds for r in res_p])
    print(f"case: {case.config.name}  n_z = {case.params.n_z}  residuals = "
          f"{int((case.target.weight > 0).sum())}  seed = {a.seed}")
    print(f"objective at z0: numpy {f_np:.10g}  CasADi {f_ca:.10g}\n")
    print(f"1-4. local solves from {n_local} starts (z0 + uniform +-20 % of bound width)")
    print(table(header, rows))
    acc = sum(r.status == "Solved_To_Acceptable_Level" for r in res_i)
    fails = sorted({r.status for r in res_s if not r.success})
    print(f"ipopt: {acc}/{n_local} stopped at the acceptable level (1e-8), counted as success;"
          f" sqpmethod failures: {', '.join(fails) or 'none'}")
    print(f"speed-up scipy / ipopt (median): {t_p / t_i:.1f}x   "
          f"scipy / sqpmethod: {t_p / np.median([r.seconds for r in res_s]):.1f}x\n")

    search = scatter_search(ipopt, SearchConfig(starts=n_starts, trial_factor=10, seed=a.seed,
                                                workers=WORKERS), progress=None)
    rows = [["CasADi ipopt scatter search", f"{search.seconds:.1f}",
             *quality(search.results, case, ipopt, truth)]]
    rows.append(scipy_multistart_row(residual, search, t_p, case, ipopt, truth))
    print(f"5. multi-start, {n_starts} starts, {WORKERS} workers")
    print(table(["method", "wall [s]", "within 1 %", "best f", "max mass err",
                 "max stiff err"], rows))
    print(f"speed-up scipy / ipopt (multi-start): "
          f"{float(rows[1][1].lstrip('~')) / search.seconds:.1f}x")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
