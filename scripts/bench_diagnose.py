"""Wall time of `frf-nlp diagnose` on a 5-storey frame with a 200-s random record.

The case comes from nlp/testing/benchmark.py (shaker at floor 1, 1 % sensor noise,
Welch H1 FRFs; an added mass at floor 3 unless --null). Prints the time of the whole
diagnosis and its verdict.

    python scripts/bench_diagnose.py [--seconds 200] [--storeys 5] [--null] [--seed 0] [--workers 2]
"""

import argparse
import os
import tempfile
import time

from nlp.case.load import load_case
from nlp.diagnosis.driver import diagnose
from nlp.testing.benchmark import make_case
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--storeys", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--null", action="store_true", help="no concealed effect")
    ap.add_argument("--workers", type=int, default=2, help="worker processes for the refits")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        spec = {"storeys": a.storeys, "seconds": a.seconds, "excitation": "force",
                "family": None if a.null else "added_mass"}
        if not a.null:
            spec.update(location=3, value=1.5)
        make_case(os.path.join(tmp, "case"), spec, a.seed)
        cfg = load_case(os.path.join(tmp, "case", "case.yaml"), {"workers": a.workers})
        t0 = time.perf_counter()
        res = diagnose(cfg, os.path.join(tmp, "out"), log=lambda *_: None)
        dt = time.perf_counter() - t0
    found = ", ".join(f"{f['physics']} {f['location']}" for f in res["findings"]) or "-"
    print(f"diagnose: {a.storeys} storeys, {a.seconds:g} s random record, force at floor 1: "
          f"{dt:.1f} s wall ({a.workers} workers, {os.cpu_count()} cores); verdict "
          f"{res['verdict']}; found {found}")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
