"""A development null of the lab generator written again with its joints taken out.

The two-level lab nulls are named as a level dependence; the joints (links.joints) are the
generator's only level-dependent part, so the same null without them says whether the joints
or the two levels' different noise and weights make the finding. The records are the same
draw otherwise: the noise comes from its own generator (write_records, seed + 1) and nothing
after the joints draws from the case's generator on a null.

    python research/nulls_without_joints.py --out DIR --seed 7 --only 6

Development seeds only (0-99).
"""

import argparse
import os

import numpy as np

import nlp.testing.lab.cases as lab_cases
from nlp.testing.lab.cases import case_name, make_case, specs


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--only", type=int, nargs="+", required=True)
    a = ap.parse_args()
    if not 0 <= a.seed <= 99:
        raise SystemExit("nulls_without_joints: --seed: expected a development seed, 0-99")
    lab_cases.joints = lambda *args, **kw: []
    all_specs = specs(np.random.default_rng(a.seed))
    for k in a.only:
        s = all_specs[k]
        if s["category"] != "null_lab":
            raise SystemExit(f"nulls_without_joints: --only {k}: case {k} is not a null")
        name = case_name(k, s) + "_no_joints"
        make_case(os.path.join(a.out, name), s, a.seed * 1000 + k, base_channel=False,
                  prior=[0.05, 0.15])  # as make_lab_benchmark.py writes them
        print(f"wrote {a.out}/{name}", flush=True)


if __name__ == "__main__":
    main()
