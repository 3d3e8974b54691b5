"""The ``frf-nlp`` command: thin layer over config, case, search and results."""

import argparse
import os
import sys

from .errors import InputError, SearchFailed
from .executors import EXECUTORS

__all__ = ["main"]


def _run(args):
    from .config import load_case
    from .workflow import run

    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed,
                                "workers": args.workers, "solver": args.solver,
                                "executor": args.executor, "scheduler": args.scheduler})
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(cfg.path), "results"))
    return run(cfg, out, resume=args.resume)


def _diagnose(args):
    from .config import load_case
    from .diagnose import diagnose

    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed, "workers": None,
                                "solver": None})
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(cfg.path), "diagnosis"))
    diagnose(cfg, out)
    print(f"wrote {out}/diagnosis.json, residual_map.png, frf_diagnosis_*.png")
    return 0


def _batch(args):
    from .batch import find_records, run_batch
    from .config import load_case

    cfg = load_case(args.case, {"starts": args.starts, "seed": args.seed, "workers": None,
                                "solver": None})
    records = find_records(args.records)
    out = os.path.abspath(args.out or os.path.join(os.path.dirname(cfg.path), "batch"))
    return run_batch(cfg, records, out, workers=args.workers or 1, resume=args.resume)


def _report(args):
    from .report import write_report

    print(f"wrote {write_report(os.path.abspath(args.dir))}")
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
    run.add_argument("--executor", choices=EXECUTORS,
                     help="where local solves run: local processes (default) or a Dask cluster")
    run.add_argument("--scheduler", help="Dask scheduler address tcp://host:port (with "
                     "--executor dask; without it a LocalCluster of --workers processes)")
    run.add_argument("--resume", action="store_true", help="continue an interrupted run into "
                     "the same --out from its checkpoint (DIR.partial/)")
    dg = sub.add_parser("diagnose", help="find what physics the model leaves out")
    dg.add_argument("case", help="case YAML file")
    dg.add_argument("--out", help="output folder (default: diagnosis/ beside the case file)")
    dg.add_argument("--starts", type=int, help="baseline starts (a quarter are used)")
    dg.add_argument("--seed", type=int, help="seed of the start points")
    bt = sub.add_parser("batch", help="update the same model from every record (monitoring)")
    bt.add_argument("case", help="case YAML file (data.file is replaced by each record)")
    bt.add_argument("records", nargs="+", help="record files, folders or glob patterns")
    bt.add_argument("--out", help="output folder (default: batch/ beside the case file)")
    bt.add_argument("--starts", type=int, help="local solves per record")
    bt.add_argument("--seed", type=int, help="seed of the trial points")
    bt.add_argument("--workers", type=int, help="records updated at once (worker processes)")
    bt.add_argument("--resume", action="store_true", help="keep the records an interrupted "
                    "batch finished and update only the rest")
    rep = sub.add_parser("report", help="rebuild report.html of a finished run folder")
    rep.add_argument("dir", help="the run's output folder")
    return ap


def main(argv=None):
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
