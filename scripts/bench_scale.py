"""How the updating cost grows with the model size n (issue 9): shear frames from 4 to 2,000 DOFs.

For each n: an n-storey shear frame (floor masses 1000 kg, known and fixed; story
stiffnesses in 8 contiguous groups, one free relative change per group; Rayleigh
damping, 2 free coefficients), ground (shake-table) input, absolute accelerations at
4 floors, the first 4 modes with 40 points per mode (+-5 % around each peak), 0.5 %
noise on magnitude and phase. The "measured" FRFs come from this script's own
simulator (modal superposition over all undamped modes, exact for Rayleigh damping;
the package's FRF code is not used), the truth being group changes drawn from
np.random.default_rng(seed).

Printed per n: the backend that ran (auto choice unless --backend), build + compile
time with an empty compile cache, the median local solve over the starts (z0 and
uniform perturbations of +-20 % of the bounds), the median iteration count, the
largest relative error of the 8 stiffness groups at the best solve, and the
objective at the best solve against its expected value at the truth (half the
number of residuals times the noise variance). Then the least-squares slope of
log(median solve) against log(n) for n >= 64 (the growth exponent).

Run:  python scripts/bench_scale.py [--sizes 4 8 16 ...] [--starts 3] [--seed 0]
      [--backend auto|dense|sparse|reduced] [--case CASE.yaml ...]
--case adds imported-model cases (one `assemble` + local solves from z0; parameter
error against the case folder's truth.json: {"alpha": {name: relative change}} or
{name: physical value}). With search.band_continuation its continuation start
competes (not counted in the median solve). A reduced-backend case is then re-centred as `frf-nlp run`
does (nlp.workflow.recentre): its passes' local-solve times and the final reduced-vs-exact
FRF error are printed under its row, and its parameter error is the re-centred one.
"""

import os


import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402

from nlp.model.damping import RayleighDamping  # noqa: E402
from nlp.frf.backends import reduced  # noqa: E402
from nlp.frf.backends.system import LinearSystem  # noqa: E402
from nlp.model.nominal import shear_frame  # noqa: E402
from nlp.model.parameters import Parameter, ParameterSet  # noqa: E402
from nlp.solve.problem import Channel, Target, UpdatingProblem  # noqa: E402
from nlp.case.assemble import assemble, build_problem  # noqa: E402
from nlp.case.load import load_case  # noqa: E402
from nlp.solve.continuation import band_continuation  # noqa: E402
from nlp.workflow.recentre import recentre  # noqa: E402
from nlp.solve.executors.threads import limit_blas_threads

SIZES = (4, 8, 16, 32, 64, 128, 256, 512, 1000, 2000)
GROUPS = 8
MODES = 4
POINTS = 40
NOISE = 0.005
ZETA = 0.02


def groups_of(n):
    """Story indices of each stiffness group (contiguous, as equal as possible)."""
    return [g for g in np.array_split(np.arange(n), min(GROUPS, n)) if g.size]


def simulate(m, k, omega, dofs, a0, a1):
    """Absolute accelerance of `dofs` for ground input by modal superposition (all modes).

    Lumped masses: M^-1/2 K M^-1/2 is tridiagonal, solved by eigh_tridiagonal.
    Rayleigh damping is diagonal in the undamped modes (zeta_r = a0/(2 w_r) + a1 w_r / 2).
    """
    n = k.size
    diag = (k + np.append(k[1:], 0.0)) / m
    off = -k[1:] / np.sqrt(m[:-1] * m[1:])
    lam, V = sla.eigh_tridiagonal(diag, off)
    wr = np.sqrt(lam)
    Phi = V / np.sqrt(m)                       # mass-normalised
    gamma = Phi.T @ (-m * np.ones(n))          # phi_r^T b, b = -M 1
    den = wr[:, None] ** 2 - omega[None, :] ** 2 + 1j * omega[None, :] * (a0 + a1 * wr[:, None] ** 2)
    Hq = (Phi[dofs] * gamma) @ (1.0 / den)     # relative receptance
    return -(omega ** 2) * Hq + 1.0            # absolute accelerance


def frame_problem(n, seed, backend):
    rng = np.random.default_rng(seed + n)
    m = np.full(n, 1000.0)
    k = np.full(n, 2.0e6) * np.linspace(1.5, 1.0, n)
    groups = groups_of(n)
    change = rng.uniform(-0.15, 0.15, len(groups))
    k_true = k.copy()
    for g, c in zip(groups, change):
        k_true[g] *= 1 + c
    # nominal band and Rayleigh coefficients (ratio ZETA at modes 1 and MODES)
    lam = sla.eigh_tridiagonal((k_true + np.append(k_true[1:], 0)) / m, -k_true[1:] / m[1:],
                               eigvals_only=True, select="i", select_range=(0, min(MODES, n) - 1))
    wn = np.sqrt(lam)
    wi, wj = wn[0], wn[-1] if wn.size > 1 else 2 * wn[0]
    a0, a1 = 2 * ZETA * wi * wj / (wi + wj), 2 * ZETA / (wi + wj)
    omega = np.concatenate([np.linspace(w * 0.95, w * 1.05, POINTS) for w in wn])
    dofs = sorted(set(np.linspace(0, n - 1, 4).round().astype(int).tolist()))
    H = simulate(m, k_true, omega, dofs, a0, a1)
    H = H * np.exp(rng.normal(0, NOISE, H.shape) + 1j * rng.normal(0, NOISE, H.shape))
    model = shear_frame(m, k)
    damping = RayleighDamping(a0_ref=a0 * 0.8, a1_ref=a1 * 1.2)  # initial damping off by 20 %
    tie = {int(s): f"g{i + 1}" for i, g in enumerate(groups) for s in g}
    ps = [Parameter(f"k{r + 1}", "stiffness", 0.0, -0.5, 1.0, tie=tie[r]) for r in range(n)]
    ps += [Parameter(f"m{r + 1}", "mass", 0.0, -0.5, 1.0, fixed=True) for r in range(n)]
    ps += [Parameter(nm, "damping", 1.0, 0.05, 20.0) for nm in damping.names]
    params = ParameterSet(tuple(ps), n, n)
    chans = tuple(Channel(f"floor{d + 1}", d, "absolute_accelerance") for d in dofs)
    target = Target(omega=omega, H=H, weight=np.ones(H.shape), channels=chans)
    truth = np.array([change[i] for i in range(len(groups))])
    return model, damping, params, target, truth, backend


def starts(problem, count, seed):
    lo, hi = problem.bounds
    z0 = np.clip(problem.z0, lo, hi)
    dz = np.random.default_rng(seed).uniform(-0.2, 0.2, (count - 1, z0.size)) * (hi - lo)
    return [z0] + list(np.clip(z0 + dz, lo, hi))


def cold_build(build):
    """Build with an empty compile cache (gcc runs for the dense backend)."""
    old = os.environ.get("FRF_NLP_CACHE")
    with tempfile.TemporaryDirectory() as tmp:
        os.environ["FRF_NLP_CACHE"] = tmp
        t0 = time.perf_counter()
        problem = build()
        seconds = time.perf_counter() - t0
    if old is None:
        del os.environ["FRF_NLP_CACHE"]
    else:
        os.environ["FRF_NLP_CACHE"] = old
    return problem, seconds


def run_frame(n, args):
    model, damping, params, target, truth, backend = frame_problem(n, args.seed, args.backend)
    def build_frame():
        basis = None
        if backend == "reduced":  # fixed basis from the nominal model (nlp.frf.backends.reduced)
            full = LinearSystem.from_model(model, damping, target)
            basis = reduced.basis(full, float(target.omega.max()))
        return UpdatingProblem(model, damping, params, target, frf_backend=backend, basis=basis)

    problem, build = cold_build(build_frame)
    results = [problem.solve(z) for z in starts(problem, args.starts, args.seed)]
    best = min(results, key=lambda r: r.f)
    z_groups = best.z[:truth.size]  # the group variables come first (alpha, scale 1)
    err = np.max(np.abs((1 + z_groups) / (1 + truth) - 1))
    expected = 0.5 * target.H.size * NOISE ** 2
    return {"n": n, "backend": problem.backend, "build": build,
            "solve": float(np.median([r.seconds for r in results])),
            "iters": float(np.median([r.iterations for r in results])),
            "ok": sum(r.success for r in results), "runs": len(results), "err": err,
            "f": best.f, "f_expected": expected, "n_z": params.n_z, "N": target.omega.size}


def run_case(path, args):
    case = assemble(load_case(path))
    problem, build = cold_build(lambda: build_problem(case))
    results = [problem.solve(z) for z in starts(problem, args.starts, args.seed)]
    best = min(results, key=lambda r: r.f)
    if case.config.search.band_continuation:  # as frf-nlp run does: one more start
        c_problem, c_res = band_continuation(case, case.config.search.band_continuation,
                                             log=lambda m: None)
        if c_res.success and c_res.f < best.f:
            problem, best = c_problem, c_res
    recentred = None
    if problem.backend == "reduced":  # as frf-nlp run does: re-centre the basis on the fit
        problem, best, recentred = recentre(case, problem, best, log=lambda m: None)
    err = float("nan")
    truth_file = os.path.join(os.path.dirname(os.path.abspath(path)), "truth.json")
    if os.path.exists(truth_file):
        with open(truth_file) as fh:
            truth = json.load(fh)
        theta = problem.theta(best.z)
        rel = truth.get("alpha", {})  # relative changes, or physical values by name
        errs = [abs((1 + t) / (1 + rel[p.name]) - 1) if p.name in rel else
                abs(p.nominal * (1 + t) / truth[p.name] - 1)
                for p, t in zip(case.params.params, theta)
                if p.group == "stiffness" and not p.fixed and (p.name in rel or p.name in truth)]
        err = max(errs) if errs else float("nan")
    return {"n": case.model.n, "backend": problem.backend, "build": build,
            "solve": float(np.median([r.seconds for r in results])),
            "iters": float(np.median([r.iterations for r in results])),
            "ok": sum(r.success for r in results), "runs": len(results), "err": err,
            "f": best.f, "f_expected": float("nan"), "n_z": case.params.n_z,
            "N": case.target.omega.size, "name": case.config.name, "recentred": recentred}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    ap.add_argument("--starts", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--backend", default="auto", choices=("auto", "dense", "sparse", "reduced"))
    ap.add_argument("--case", nargs="*", default=[])
    args = ap.parse_args()
    head = (f"{'model':<22}{'n':>6}{'n_z':>5}{'N':>5}  {'backend':<8}{'build+compile [s]':>18}"
            f"{'median solve [s]':>17}{'iters':>7}{'ok':>6}{'max group err':>15}"
            f"{'f / f_noise':>12}")
    print(f"shear frames: {GROUPS} stiffness groups + 2 Rayleigh, {MODES} modes x {POINTS} points, "
          f"4 accelerometers, {NOISE:.1%} noise, {args.starts} starts, seed {args.seed}")
    print(head)
    print("-" * len(head))
    rows = []
    for n in args.sizes:
        r = run_frame(n, args)
        rows.append(r)
        print(f"{'shear frame':<22}{n:>6}{r['n_z']:>5}{r['N']:>5}  {r['backend']:<8}{r['build']:>18.2f}"
              f"{r['solve']:>17.3f}{r['iters']:>7.0f}{r['ok']:>3}/{r['runs']:<2}{r['err']:>15.2%}"
              f"{r['f'] / r['f_expected']:>12.2f}", flush=True)
    for path in args.case:
        r = run_case(path, args)
        print(f"{r['name'][:21]:<22}{r['n']:>6}{r['n_z']:>5}{r['N']:>5}  {r['backend']:<8}"
              f"{r['build']:>18.2f}{r['solve']:>17.3f}{r['iters']:>7.0f}{r['ok']:>3}/{r['runs']:<2}"
              f"{r['err']:>15.2%}{'-':>12}", flush=True)
        rc = r["recentred"]
        if rc:
            fc = rc["final_check"]
            print(f"{'':<22}re-centred basis: {len(rc['passes'])} passes, local solve per pass "
                  + ", ".join(f"{p['seconds']:.1f}" for p in rc["passes"])
                  + f" s (iterations {', '.join(str(p['iterations']) for p in rc['passes'])}), "
                  f"last move {rc['passes'][-1]['max_move_se']:.2g} SE; reduced vs exact RMS ln|H| "
                  f"{fc['rms_log_error']:.2g} (noise {fc['noise']:.2g}, {fc['points_checked']} points)"
                  f"; max group err above is after re-centring", flush=True)
    big = [r for r in rows if r["n"] >= 64]
    if len(big) >= 2:
        slope, _ = np.polyfit(np.log([r["n"] for r in big]), np.log([r["solve"] for r in big]), 1)
        print(f"growth exponent of the median local solve in n (n >= 64, least squares on logs): "
              f"{slope:.2f}")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
