"""Lab benchmark for `frf-nlp diagnose`: the blind benchmark's recipe in an imperfect lab.

Writes every case of the list (or those of --only) under --out: records, case.yaml
(written by the blind benchmark's recipe from the test description only) and truth.json
(category, the verdicts a right answer may give, the location it must name, every lab
imperfection drawn). nlp/testing/lab/ holds the lab (docs/benchmarks/lab_generator.md
describes each imperfection and its size); it shares no code with the package.

    python scripts/make_lab_benchmark.py --out lab --seed SEED [--only 0-7] [--base-channel]
    python scripts/make_lab_benchmark.py --out sweep --seed SEED --rho 0.5,1,2,5

--rho writes, instead of the case list, one flexible-beam frame per beam-column stiffness
ratio (the frame-action sweep of issue 46), numbered from 100 so that no case seed
collides with the list's; storeys, input and signal are drawn as the list draws them.

Seeds 0-99 are development seeds; an exam seed is drawn after the freeze (issue 48).
The case list and every random draw come from --seed.
"""

import argparse
import os
import time

import numpy as np

from nlp.testing.lab.cases import case_name, make_case, specs
from nlp.testing.blind.cases import case_numbers
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="lab")
    ap.add_argument("--seed", type=int, required=True,
                    help="development: 0-99; an exam seed is drawn after the code freeze")
    ap.add_argument("--only", help="case numbers, e.g. 0-7 or 3,17,30")
    ap.add_argument("--base-channel", action="store_true",
                    help="list the table accelerometer (floor 0) in the shake-table case files")
    ap.add_argument("--prior", default="0.05,0.15",
                    help="relative 1-sigma uncertainty of the design masses and stiffnesses "
                         "(as the blind benchmark; 'none' leaves it out)")
    ap.add_argument("--residual", default="log_magnitude")
    ap.add_argument("--rho", help="comma-separated beam-column stiffness ratios: write only "
                                  "flexible-beam frames, one per ratio")
    a = ap.parse_args()
    if a.rho:
        todo = list(enumerate(rho_specs(a.seed, [float(x) for x in a.rho.split(",")]), start=100))
    else:
        all_specs = specs(np.random.default_rng(a.seed))
        todo = [(k, all_specs[k]) for k in case_numbers(a.only, len(all_specs))]
    for k, s in todo:
        name = case_name(k, s)
        t0 = time.perf_counter()
        make_case(os.path.join(a.out, name), s, a.seed * 1000 + k, base_channel=a.base_channel,
                  residual=a.residual,
                  prior=None if a.prior == "none" else [float(x) for x in a.prior.split(",")])
        print(f"wrote {a.out}/{name} ({time.perf_counter() - t0:.0f} s)", flush=True)


def rho_specs(seed, ratios):
    """Flexible-beam frame specs at the given ratios, the rest drawn as specs() draws them."""
    rng = np.random.default_rng([seed, 46])
    return [{"category": "non_shear", "rho": r, "storeys": int(rng.integers(3, 6)),
             "excitation": str(rng.choice(["ground", "force"])),
             "signal": str(rng.choice(["chirp", "random"]))} for r in ratios]


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
