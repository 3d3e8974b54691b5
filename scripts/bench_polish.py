"""One baseline solve of a diagnosis with and without the Newton polish (nlp/solve/polish.py).

    python scripts/bench_polish.py CASE.yaml [--solves 2]

Builds the baseline problem `frf-nlp diagnose` fits first (the case's half-power
windows, residuals over the noise model) and solves it from the case's initial point:
once as IPOPT alone with the Gauss-Newton Hessian (the stall stop and the polish off),
once as shipped (IPOPT stopped where it stalls, then Newton steps on the full Hessian).
Each solve is repeated from where the last ended (--solves). Prints iterations, wall
seconds, f (= chi-square / 2), the status, and the Gauss-Newton decrement at the end.
"""

import argparse
import time

from nlp.diagnosis.fitting import diagnosis_problem, fit_target, fit_windows, noise_sigma
from nlp.solve import problem as pm
from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.solve.executors.threads import limit_blas_threads


def run(label, case, target, solves):
    pr = diagnosis_problem(case, target)
    z = pr.z0
    for k in range(solves):
        t0 = time.perf_counter()
        r = pr.solve(z)
        dt = time.perf_counter() - t0
        print(f"{label:<22} solve {k + 1}: {r.iterations:5d} iterations {dt:6.1f} s  "
              f"f {r.f:.4f}  {'converged' if r.success else 'NOT converged'} ({r.status}); "
              f"Gauss-Newton decrement {pr.gn_decrement(r.z):.3g}", flush=True)
        z = r.z


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", help="case YAML")
    ap.add_argument("--solves", type=int, default=2, help="solves in a row (default 2)")
    args = ap.parse_args(argv)
    cfg = load_case(args.case)
    case = assemble(cfg)
    fit = fit_windows(cfg, case, 1)
    target = fit_target(case, fit, noise_sigma(case, fit))
    print(f"{args.case}: {len(case.channels)} channels x {len(fit)} frequencies")
    keep = pm.MAX_PARAMETERS
    pm.MAX_PARAMETERS = 0          # no stall stop, no polish: IPOPT alone
    try:
        run("IPOPT (Gauss-Newton)", case, target, args.solves)
    finally:
        pm.MAX_PARAMETERS = keep
    run("IPOPT + Newton polish", case, target, args.solves)


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
