"""Concealed-effect benchmark for `frf-nlp diagnose`.

Every case is a 3- to 5-storey shear frame whose "real" structure differs from
the case file's nominal model by ordinary parameter changes (stories 0-15 %
softer or stiffer) and, in most cases, by one piece of missing physics. Tests
are simulated as noisy time histories (band-limited random ground
acceleration on a shake table, or a random force from a shaker at one floor;
accelerometers with 1 % noise) and turned into H1 FRFs by the case file
itself. Floor masses are weighed (fixed); damping is Rayleigh in the model.
Truth goes to truth.json, which `diagnose` never reads; score_benchmark.py does.
The simulation is in nlp/testing/benchmark.py.

    python scripts/make_benchmark.py [--out benchmark] [--seed 0] [--per-family 2]
"""

import argparse
import os

import numpy as np

from nlp.testing.benchmark import make_case, specs
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="benchmark")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--per-family", type=int, default=2)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    for k, s in enumerate(specs(rng, a.per_family)):
        name = f"{k:02d}_{s['family'] or ('ordinary' if s.get('ordinary') else 'null')}"
        make_case(os.path.join(a.out, name), s, a.seed * 1000 + k)
        print(f"wrote {a.out}/{name}")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
