"""The ``frf-nlp`` command: thin layer over config, case, search and results."""

import argparse
import os
import sys

from .errors import InputError
from .outdir import check_writable, locked_folder, output_folder, prev_path

__all__ = ["main"]


def _out(args, default):
    """The --out folder, checked for writing before any work (creates nothing)."""
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(os.path.abspath(args.case)),
                                                   default))
    check_writable(out)
    return out


def _run(args):
    from .config import load_case

    out = _out(args, "results")
    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed,
                                "workers": args.workers, "solver": args.solver})
    from .workflow import run
    with output_folder(out, "run") as stage:
        status = run(cfg, stage)
        stage.interrupted = status == 130
    print(f"wrote {out}: summary.json, result.json, parameters.csv, figures, report.html"
          + (f" (previous result in {prev_path(out)})" if os.path.isdir(prev_path(out)) else ""))
    return status


def _diagnose(args):
    from .config import load_case

    out = _out(args, "diagnosis")
    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed, "workers": None,
                                "solver": None})
    from .diagnose import diagnose
    with output_folder(out, "diagnose") as stage:
        diagnose(cfg, stage)
    print(f"wrote {out}/diagnosis.json, residual_map.png, frf_diagnosis_*.png")
    return 0


def _report(args):
    from .report import write_report

    with locked_folder(os.path.abspath(args.dir)) as d:
        print(f"wrote {write_report(d)}")
    return 0


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
    dg = sub.add_parser("diagnose", help="find what physics the model leaves out")
    dg.add_argument("case", help="case YAML file")
    dg.add_argument("--out", help="output folder (default: diagnosis/ beside the case file)")
    dg.add_argument("--starts", type=int, help="baseline starts (a quarter are used)")
    dg.add_argument("--seed", type=int, help="seed of the start points")
    rep = sub.add_parser("report", help="rebuild report.html of a finished run folder")
    rep.add_argument("dir", help="the run's output folder")
    return ap


def main(argv=None):
    args = _parser().parse_args(argv)
    try:
        return {"run": _run, "diagnose": _diagnose, "report": _report}[args.command](args)
    except InputError as exc:
        print(f"frf-nlp: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("frf-nlp: interrupted before any result was ready", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
