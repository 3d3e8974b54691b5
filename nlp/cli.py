"""The ``frf-nlp`` command: thin layer over config, case, search and results."""

import argparse
import os
import sys
import time

from .errors import InputError

__all__ = ["main"]


def _run(args):
    from .case import assemble, build_problem
    from .config import load_case
    from .plots import plot_frf_overlays
    from .results import parameters_table, summarize, write_atomic, write_json
    from .search import SearchConfig, scatter_search

    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed,
                                "workers": args.workers, "solver": args.solver})
    case = assemble(cfg)
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(cfg.path), "results"))
    print(f"case {cfg.name}: {case.model.n} DOF, {case.params.n_z} free parameters, "
          f"{len(case.channels)} channels x {case.selected.size} frequency points "
          f"({case.f[case.selected].min():.3g}-{case.f[case.selected].max():.3g} Hz), "
          f"residual {cfg.objective.residual}, solver {cfg.solver.name}")
    t0 = time.perf_counter()
    problem = build_problem(case)
    print(f"NLP built in {time.perf_counter() - t0:.2f} s "
          f"({'compiled C' if problem.compiled else 'CasADi virtual machine'})")
    s = cfg.search
    search = scatter_search(problem, SearchConfig(starts=s.starts, trial_factor=s.trial_factor,
                                                  seed=s.seed, workers=s.workers))
    result = summarize(case, problem, search)
    write_json(os.path.join(out, "result.json"), result)
    table = parameters_table(result)
    write_atomic(os.path.join(out, "parameters.csv"), table)
    mats = result["matrices"]
    plot_frf_overlays(out, case, tuple(mats["initial"][k] for k in "MKC"),
                      tuple(mats["updated"][k] for k in "MKC"))
    _print_summary(result, table, out)
    return 130 if search.interrupted else 0


def _print_summary(result, table, out):
    srch = result["search"]
    print(f"search: {srch['starts_finished']}/{srch['starts_requested']} local solves in "
          f"{srch['seconds']:.2f} s; {srch['starts_within_1pct_of_best']} within 1 % of the best"
          + ("  (INTERRUPTED: partial result)" if srch["interrupted"] else ""))
    obj = result["objective"]
    print(f"objective: {obj['initial']:.4g} -> {obj['updated']:.4g}  "
          f"(best start: {result['solver']['status']}, {result['solver']['iterations']} iterations)")
    print()
    for line in table.strip().splitlines()[:4]:
        print("  " + line.replace(",", "\t"))
    print()
    f0 = result["modal"]["updated"]["natural_frequencies_hz"]
    z0 = result["modal"]["updated"]["damping_ratios"]
    print("updated modes: " + ", ".join(f"{f:.3f} Hz ({100 * z:.2f} %)" for f, z in zip(f0, z0)))
    print("FDAC updated: " + ", ".join(f"{k} {v:.4f}" for k, v in result["fdac"]["updated"].items()))
    for wk in result["identifiability"]["weak_directions"]:
        print(f"warning: weakly identified combination {wk['combination']} "
              f"(sigma ratio {wk['sigma_ratio']:.1e})")
    print(f"wrote {out}/result.json, parameters.csv, frf_*.png")


def _parser():
    ap = argparse.ArgumentParser(prog="frf-nlp", description="FRF-based model updating "
                                 "with general viscous damping (CasADi NLP).")
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="update the model of a case file")
    run.add_argument("case", help="case YAML file")
    run.add_argument("--out", help="output folder (default: results/ beside the case file)")
    run.add_argument("--starts", type=int, help="local solves in the scatter search")
    run.add_argument("--seed", type=int, help="seed of the trial points")
    run.add_argument("--workers", type=int, help="worker processes")
    run.add_argument("--solver", help="ipopt or sqpmethod (overrides the case file)")
    return ap


def main(argv=None):
    args = _parser().parse_args(argv)
    try:
        return _run(args)
    except InputError as exc:
        print(f"frf-nlp: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("frf-nlp: interrupted before any result was ready", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
