"""Blind benchmark for `frf-nlp diagnose`: tests the package was not built on.

Writes every case of the list (or those of --only) under --out: records (or
frf.npz), case.yaml and truth.json, which only scripts/score_blind.py reads. The
structures, signals, simulators, sensors and the case recipe are in
nlp/testing/blind/ (its docstring describes them); they share no code with the package.

    python scripts/make_blind_benchmark.py --out blind --seed SEED [--only 0-11] [--check]

Seeds: see the README ("Blind benchmark"). The case list and every random draw
come from --seed.
"""

import argparse
import os

import numpy as np

from nlp.testing.blind.cases import case_name, case_numbers, check_case, make_case, specs
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="blind")
    ap.add_argument("--seed", type=int, required=True,
                    help="development: 0-99; scoring: fixed after the code freeze (README)")
    ap.add_argument("--only", help="case numbers, e.g. 0-11 or 3,17,40")
    ap.add_argument("--base-channel", action="store_true",
                    help="list the table accelerometer (floor 0) in the shake-table case files "
                         "(the records always carry it)")
    ap.add_argument("--prior", default="0.05,0.15",
                    help="relative 1-sigma uncertainty of the design masses and stiffnesses "
                         "written as parameters.prior (default 0.05,0.15: design tolerances of "
                         "+-10 %% and +-30 %% read as two sigmas; 'none' leaves it out)")
    ap.add_argument("--check", action="store_true",
                    help="after writing, compare each linear case's FRF estimate with the exact FRF")
    ap.add_argument("--residual", default="log_magnitude",
                    help="objective.residual written by the recipe (log_magnitude or complex)")
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    all_specs = specs(rng)
    for k in case_numbers(a.only, len(all_specs)):
        s = all_specs[k]
        name = case_name(k, s)
        make_case(os.path.join(a.out, name), s, a.seed * 1000 + k,
                  base_channel=a.base_channel, residual=a.residual,
                  prior=None if a.prior == "none" else [float(x) for x in a.prior.split(",")])
        msg = check_case(os.path.join(a.out, name)) if a.check else ""
        print(f"wrote {a.out}/{name}{msg}", flush=True)


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
