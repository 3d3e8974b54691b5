"""How updating scales with the model (issue 47): tall shear frames with one parameter per
storey, and imported cases (the 2,100-DOF frame).

Tall frames (nlp/testing/tall.py, data by an independent modal sum, not the package's
FRF code): n storeys, masses 5 % and stiffnesses 10 % off the truth, floor 1 weighed,
2 n + 1 free parameters (n stiffnesses, n - 1 masses, 2 Rayleigh coefficients), ground
input, receptances at 4 floors, 40 n points from 0.5 f1 to 1.1 fn, 0.5 % noise. Each is
written as a case folder and run as `frf-nlp run` runs it (nlp.api.run: 4 starts).
The sizes of --weighed (default 256) are run again with every floor weighed: n + 2 free
parameters. research/tall_design.py shows why: at n = 256 the Cramer-Rao standard errors of
free per-storey masses and stiffnesses are hundreds of per cent with these data, those of
the stiffnesses alone, masses known, at most 0.2 %. The sizes of --every-floor (default 256)
are run again, masses free, with a receptance at every floor and n points (one a storey):
Cramer-Rao errors of at most 0.15 % at n = 256.

Printed per model:
  build      seconds to assemble the case and build the NLP (compile included; a cold cache)
  eval       median seconds of one residual-plus-Jacobian evaluation at z0 (3 calls), and
             its ratio to the flop-and-memory bound of docs/method/backends.md
             ("Cost of one evaluation", nlp.frf.backends.cost; banded systems only), with
             this machine's measured rates
  iters      local-solver iterations of the best start: prefit + main
  solve      median seconds of a local solve
  run        whole run (all starts, polishing, reporting), wall seconds
  cpu        its CPU seconds (this process and its finished worker processes), and the
             1-minute load average at its end: on a shared machine wall time is not the
             target figure
  k err      largest |k_fit / k_true - 1| over the storeys, and the largest |error| / SE
  flags      the result's flags
Then the growth exponent of the evaluation and of the whole run in n (least squares on
logs over the frames run).

Run:  python scripts/bench_scale.py [--sizes 16 32 64 256] [--starts 4] [--workers 2]
      [--frequencies default|all] [--case cases/frame3d_2100/case.yaml ...]
      [--weighed 256] [--every-floor 256] [--eval-only 1024]   (sizes whose whole run is not attempted: build and one evaluation)
      [--lm auto|none|prefit|all]   (Levenberg-Marquardt prefits or local solves,
      nlp/solve/lm.py; auto: the package's default, LM above LM_FROM free variables)
"""

import argparse
import json
import os
import resource
import tempfile
import time

import numpy as np
import yaml

import nlp
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.frf.backends.cost import evaluation_cost, machine_rates
from nlp.solve.executors.threads import limit_blas_threads
from nlp.solve.problem import UpdatingProblem
from nlp.testing.tall import case_dict, tall_frame


def write_frame(n, folder, frequencies, weighed="first", every_floor=False):
    fr = tall_frame(n, seed=0, sensors=n, points_per_storey=1) if every_floor else tall_frame(n, seed=0)
    os.makedirs(folder, exist_ok=True)
    np.savez_compressed(os.path.join(folder, "frf.npz"), f=fr.f, H=fr.H)
    freq = {"method": "all"} if frequencies == "all" else {}  # {}: the package's default selection
    with open(os.path.join(folder, "case.yaml"), "w") as fh:
        yaml.safe_dump(case_dict(fr, frequencies=freq, weighed=weighed), fh, sort_keys=False)
    return os.path.join(folder, "case.yaml"), fr


def build_and_eval(path, rates):
    """Build time, median evaluation time and its bound ratio, problem size."""
    with tempfile.TemporaryDirectory() as cache:
        old = os.environ.get("FRF_NLP_CACHE")
        os.environ["FRF_NLP_CACHE"] = cache
        t0 = time.perf_counter()
        case = assemble(load_case(path))
        problem = build_problem(case)
        build = time.perf_counter() - t0
        if old is None:
            del os.environ["FRF_NLP_CACHE"]
        else:
            os.environ["FRF_NLP_CACHE"] = old
    row = {"build": build, "n_z": case.params.n_z, "N": case.target.omega.size,
           "backend": problem.backend, "eval": np.nan, "ratio": np.nan}
    if problem.backend == "dense":
        return case, row
    times, z0 = [], problem.z0  # z0 outside the clock: it is not part of the evaluation
    for _ in range(3):
        problem.evaluator._last = None
        t0 = time.perf_counter()
        problem.residuals(z0)
        times.append(time.perf_counter() - t0)
    row["eval"] = float(np.median(times))
    if problem.evaluator.banded:  # the bound is written for the banded path
        cost = evaluation_cost(problem.evaluator, case.target.omega.size, problem.n_res)
        row["ratio"] = row["eval"] / (cost["flops"] / rates[0] + cost["bytes"] / rates[1])
    return case, row


def _cpu():
    """CPU seconds of this process and of its children that have ended (the workers)."""
    return sum(getattr(resource.getrusage(who), f) for who in (resource.RUSAGE_SELF,
               resource.RUSAGE_CHILDREN) for f in ("ru_utime", "ru_stime"))


def whole_run(path, out, starts, workers):
    """(result.json, wall seconds, CPU seconds, load average at the end)."""
    t0, c0 = time.perf_counter(), _cpu()
    nlp.run(path, out, log=lambda m: None, starts=starts, workers=workers)
    seconds, cpu = time.perf_counter() - t0, _cpu() - c0
    with open(os.path.join(out, "result.json")) as fh:
        return json.load(fh), seconds, cpu, os.getloadavg()[0]


def frame_errors(result, fr):
    """Largest relative stiffness error against the truth and largest |error| / SE."""
    errs, zs = [], []
    for p in result["parameters"]:
        if p["group"] != "stiffness" or p["fixed"]:
            continue
        k_true = fr.k[int(p["name"][1:]) - 1]
        se = p["standard_error"] or p["standard_error_if_interior"] or np.nan
        errs.append(abs(p["updated"] / k_true - 1))
        zs.append(abs(p["updated"] - k_true) / se)
    return max(errs), max(zs)


def case_errors(result, path):
    """Largest relative stiffness error against the case folder's truth.json ({"alpha": ...})."""
    truth_file = os.path.join(os.path.dirname(os.path.abspath(path)), "truth.json")
    if not os.path.exists(truth_file):
        return np.nan, np.nan
    with open(truth_file) as fh:
        alpha = json.load(fh).get("alpha", {})
    errs, zs = [], []
    for p in result["parameters"]:
        if p["name"] in alpha and not p["fixed"]:
            true = p["initial"] * (1 + alpha[p["name"]])
            se = p["standard_error"] or p["standard_error_if_interior"] or np.nan
            errs.append(abs(p["updated"] / true - 1))
            zs.append(abs(p["updated"] - true) / se)
    return (max(errs), max(zs)) if errs else (np.nan, np.nan)


def run_summary(result):
    best = min((s for s in result["search"]["starts"] if s["success"]),
               key=lambda s: s["f"], default=None)
    solves = [s["seconds"] for s in result["search"]["starts"]]
    return {"iters": f"{best.get('prefit_iterations', 0)}+{best['iterations']}" if best else "-",
            "solve": float(np.median(solves)) if solves else np.nan,
            "flags": ",".join(f["kind"] for f in result["flags"]) or "-"}


def print_row(name, r):
    print(f"{name:<16}{r.get('n', 0):>6}{r['n_z']:>6}{r['N']:>7}  {r['backend']:<8}"
          f"{r['build']:>7.2f}{r['eval']:>9.3f}{r['ratio']:>7.1f}"
          f"{r.get('iters', '-'):>8}{r.get('solve', np.nan):>9.1f}{r.get('run', np.nan):>9.1f}"
          f"{r.get('cpu', np.nan):>9.1f}{r.get('load', np.nan):>6.1f}"
          f"{r.get('err', np.nan):>9.2%}{r.get('z', np.nan):>8.1f}  {r.get('flags', '')}",
          flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[16, 32, 64, 256])
    ap.add_argument("--eval-only", type=int, nargs="*", default=[])
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--frequencies", choices=("default", "all"), default="default")
    ap.add_argument("--weighed", type=int, nargs="*", default=[256],
                    help="sizes also run with every floor weighed (masses fixed, n + 2 free "
                         "parameters): what a test needs at n = 256 (research/tall_design.py)")
    ap.add_argument("--every-floor", type=int, nargs="*", default=[256],
                    help="sizes also run with a receptance at every floor and n points (one a "
                         "storey), masses free: a test that determines 2 n + 1 parameters")
    ap.add_argument("--case", nargs="*", default=[])
    ap.add_argument("--lm", choices=("auto", "none", "prefit", "all"), default="auto",
                    help="Levenberg-Marquardt (nlp/solve/lm.py) for the prefits or every local "
                         "solve (auto: the package's default, above LM_FROM free variables)")
    ap.add_argument("--keep", default=None, help="folder for the cases and results (default: temporary)")
    args = ap.parse_args()
    if args.lm != "auto":  # forked workers inherit it
        UpdatingProblem.lm_prefit = args.lm in ("prefit", "all")
        UpdatingProblem.lm_local = args.lm == "all"
    rates = machine_rates()
    print(f"machine: {rates[0] / 1e9:.1f} GFlop/s (one-thread matrix product), "
          f"{rates[1] / 1e9:.1f} GB/s (array copy); {args.starts} starts, {args.workers} workers, "
          f"frequencies {args.frequencies}")
    head = (f"{'model':<16}{'n':>6}{'n_z':>6}{'N':>7}  {'backend':<8}{'build':>7}{'eval':>9}"
            f"{'/bound':>7}{'iters':>8}{'solve':>9}{'run':>9}{'cpu':>9}{'load':>6}{'k err':>9}"
            f"{'err/SE':>8}  flags")
    print(head + "\n" + "-" * len(head))
    root = args.keep or tempfile.mkdtemp(prefix="bench_scale_")
    rows = []
    runs = [(n, "first") for n in sorted(set(args.sizes) | set(args.eval_only))]
    runs += [(n, "all") for n in sorted(set(args.weighed))]
    runs += [(n, "every_floor") for n in sorted(set(args.every_floor))]
    names = {"first": "tall frame", "all": "tall, weighed", "every_floor": "tall, all floors"}
    for n, kind in runs:
        tag = f"{n}" if kind == "first" else f"{n}_{kind}"
        path, fr = write_frame(n, os.path.join(root, f"tall_{tag}"), args.frequencies,
                               "all" if kind == "all" else "first", kind == "every_floor")
        _, r = build_and_eval(path, rates)
        r["n"] = n
        if n in args.sizes or kind != "first":
            result, r["run"], r["cpu"], r["load"] = whole_run(
                path, os.path.join(root, f"out_{tag}"), args.starts, args.workers)
            r.update(run_summary(result))
            r["err"], r["z"] = frame_errors(result, fr)
        if kind == "first":
            rows.append(r)
        print_row(names[kind], r)
    for path in args.case:
        case, r = build_and_eval(path, rates)
        r["n"] = case.model.n
        result, r["run"], r["cpu"], r["load"] = whole_run(
            path, os.path.join(root, f"out_{case.config.name}"), case.config.search.starts,
            args.workers)
        r.update(run_summary(result))
        r["err"], r["z"] = case_errors(result, path)
        print_row(case.config.name[:15], r)
    ran = [r for r in rows if np.isfinite(r.get("run", np.nan))]
    for key, what in (("eval", "one evaluation"), ("run", "the whole run")):
        pts = [r for r in (rows if key == "eval" else ran) if np.isfinite(r.get(key, np.nan))]
        if len(pts) >= 2:
            slope = np.polyfit(np.log([r["n"] for r in pts]), np.log([r[key] for r in pts]), 1)[0]
            print(f"growth exponent of {what} in n (tall frames, least squares on logs): {slope:.2f}")
    print(f"cases and results in {root}")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
