"""The ``frf-nlp`` command: thin layer over the case, the workflow, diagnosis and output."""

import argparse
import os
import sys

from nlp import __version__, api
from nlp.errors import InputError, SearchFailed
from nlp.output.outdir import check_writable, locked_folder, prev_path
from nlp.output.report import write_report
from nlp.solve.executors import EXECUTORS

__all__ = ["main"]


def _out(args, default):
    """The --out folder, checked for writing before any work (creates nothing)."""
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(os.path.abspath(args.case)),
                                                   default))
    check_writable(out)
    return out


def _case(args):
    """The case file with the command line's overrides."""
    return api.load_case(args.case, starts=args.starts, seed=args.seed, workers=args.workers,
                         solver=getattr(args, "solver", None), executor=args.executor,
                         scheduler=args.scheduler)


def _run(args):
    out = _out(args, "results")
    result = api.run(_case(args), out, resume=args.resume)
    print(f"wrote {out}: summary.json, result.json, parameters.csv, figures, report.html"
          + (f" (previous result in {prev_path(out)})" if os.path.isdir(prev_path(out)) else ""))
    return result.status


def _diagnose(args):
    out = _out(args, "diagnosis")
    api.diagnose(_case(args), out, resume=args.resume, budget=args.budget)
    print(f"wrote {out}/diagnosis.json, residual_map.png, frf_diagnosis_*.png, report.html")
    return 0


def _batch(args):
    cfg = _case(args)
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(cfg.path), "batch"))
    return api.batch(cfg, args.records, out, resume=args.resume).status


def _report(args):
    with locked_folder(os.path.abspath(args.dir)) as d:
        print(f"wrote {write_report(d)}")
    return 0


_EPILOG = """exit status:
  0    done
  2    a mistake in the command line, case file or data file (one line names the file,
       the key and what is expected; nothing is written)
  3    no local solve converged (no result written)
  130  interrupted (Ctrl-C or SIGTERM); a run keeps the finished starts, a diagnosis its
       finished searches and rounds, for --resume

Case-file reference: docs/case_reference.md. Python API: docs/api (see README)."""


def _minutes(text):
    """A positive number of minutes (argparse type)."""
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not v > 0 or v == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a positive number of minutes, got {text!r}")
    return v


def _executor_arguments(p, what):
    """--workers, --executor and --scheduler, the same for run, diagnose and batch."""
    p.add_argument("--workers", type=int, help="worker processes (default: search.workers, "
                   "else 1)")
    p.add_argument("--executor", choices=EXECUTORS, help=f"where {what} run: local processes "
                   "(default: search.executor, else local) or a Dask cluster")
    p.add_argument("--scheduler", help="Dask scheduler address tcp://host:port (with "
                   "--executor dask; without it a LocalCluster of --workers processes)")


def _parser():
    ap = argparse.ArgumentParser(prog="frf-nlp", description="FRF-based model updating "
                                 "with general viscous damping (CasADi NLP).", epilog=_EPILOG,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = ap.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="update the model of a case file", epilog=_EPILOG,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    run.add_argument("case", help="case YAML file")
    run.add_argument("--out", help="output folder (default: results/ beside the case file)")
    run.add_argument("--starts", type=int, help="local solves in the scatter search (default: "
                     "the case's search.starts, else 20)")
    run.add_argument("--seed", type=int, help="seed of the trial points (default: search.seed, "
                     "else 0)")
    run.add_argument("--solver", help="ipopt or sqpmethod (default: solver.name, else ipopt)")
    _executor_arguments(run, "local solves")
    run.add_argument("--resume", action="store_true", help="continue an interrupted run into "
                     "the same --out from its checkpoint (DIR.partial/)")
    dg = sub.add_parser("diagnose", help="find what physics the model leaves out",
                        epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    dg.add_argument("case", help="case YAML file")
    dg.add_argument("--out", help="output folder (default: diagnosis/ beside the case file)")
    dg.add_argument("--starts", type=int, help="baseline starts, a quarter are used (default: "
                    "search.starts, else 20)")
    dg.add_argument("--seed", type=int, help="seed of the start points (default: search.seed, "
                    "else 0)")
    _executor_arguments(dg, "baseline starts and candidate refits")
    dg.add_argument("--resume", action="store_true", help="continue an interrupted diagnosis "
                    "into the same --out: its finished searches and rounds are taken from "
                    "the checkpoint (DIR.partial/diagnosis/)")
    dg.add_argument("--budget", type=_minutes, metavar="MINUTES", help="start no stage (the "
                    "model discrepancy, a round of candidates, the widened look) after this "
                    "many minutes: the verdict says where it stopped, and --resume with a "
                    "larger budget goes on")
    bt = sub.add_parser("batch", help="update the same model from every record (monitoring)")
    bt.add_argument("case", help="case YAML file (data.file is replaced by each record)")
    bt.add_argument("records", nargs="+", help="record files, folders or glob patterns")
    bt.add_argument("--out", help="output folder (default: batch/ beside the case file)")
    bt.add_argument("--starts", type=int, help="local solves per record")
    bt.add_argument("--seed", type=int, help="seed of the trial points")
    _executor_arguments(bt, "records (one task each)")
    bt.add_argument("--resume", action="store_true", help="keep the records an interrupted "
                    "batch finished and update only the rest")
    rep = sub.add_parser("report", help="rebuild report.html of a finished run or diagnosis "
                         "folder", epilog=_EPILOG,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    rep.add_argument("dir", help="the output folder of 'frf-nlp run' or 'frf-nlp diagnose'")
    return ap


def main(argv=None):
    """Run the ``frf-nlp`` command with ``argv`` (default ``sys.argv[1:]``); returns the
    exit status (0, 2, 3 or 130: see ``frf-nlp --help``)."""
    args = _parser().parse_args(argv)
    try:
        return {"run": _run, "diagnose": _diagnose, "batch": _batch,
                "report": _report}[args.command](args)
    except InputError as exc:
        print(f"frf-nlp: error: {exc}", file=sys.stderr)
        return 2
    except SearchFailed as exc:  # exit 3: the data or model, not the command line
        print(f"frf-nlp: error: {exc}; no result written", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print("frf-nlp: interrupted before any result was ready (finished starts are kept "
              "for --resume)", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
