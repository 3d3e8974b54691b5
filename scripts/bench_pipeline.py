"""Raw records to report on cases/four_story_shake_table, with the wall time of each stage.

    python scripts/bench_pipeline.py [--case PATH] [--out DIR] [--starts N]

Stages: read and validate the case; read the CSV records and estimate the H1
FRFs with half-power selection (both updates); build the NLPs; scatter
search; time-domain replay; report. Prints a table of seconds per stage.
"""

import argparse
import os
import time

import numpy as np

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.output.report import write_report
from nlp.solve.search import SearchConfig, scatter_search
from nlp.workflow.verify import replay
from nlp.workflow.update import run
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default=os.path.join(HERE, "..", "cases", "four_story_shake_table",
                                                   "case.yaml"))
    ap.add_argument("--out", default="/tmp/frf-nlp-bench-pipeline")
    ap.add_argument("--starts", type=int, default=20)
    a = ap.parse_args()
    times = {}

    def stage(name, fn):
        t0 = time.perf_counter()
        value = fn()
        times[name] = times.get(name, 0.0) + time.perf_counter() - t0
        return value

    cfg = stage("read case file", lambda: load_case(a.case, {"starts": a.starts}))
    models = []
    for label, chans in cfg.updates.items():
        case = stage("read CSV, H1 FRFs, half-power points", lambda: assemble(cfg, channels=chans))
        prob = stage("build NLP (compiled C, cached)", lambda: build_problem(case))
        s = cfg.search
        res = stage("scatter search", lambda: scatter_search(
            prob, SearchConfig(starts=s.starts, seed=s.seed, workers=s.workers), progress=None))
        models.append(prob.matrices(res.best.z))
    M, K, C = (np.mean([m[i] for m in models], axis=0) for i in range(3))
    reps = stage("time-domain replay", lambda: replay(M, C, K, case.records, cfg.data))
    total = stage("whole command (frf-nlp run, incl. figures, report)",
                  lambda: run(cfg, a.out, log=lambda *_: None))
    stage("rebuild report.html only", lambda: write_report(a.out))
    print(f"case {cfg.name}: {case.records.t.size} samples x {len(cfg.data.channels) + 1} channels, "
          f"{len(cfg.updates)} updates x {a.starts} starts; 4th-floor NRMSE "
          f"{100 * reps['a4']['nrmse']:.2f} % (exit {total})")
    w = max(len(k) for k in times)
    for k, v in times.items():
        print(f"  {k:<{w}}  {v:8.3f} s")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
