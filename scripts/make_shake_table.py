"""Simulate the paper's shake-table test (Section 4.1) on the four-story frame.

Ground motion: a linear chirp from 0 to 10 Hz in 60 s, 1 m/s^2 amplitude,
sampled at 200 Hz, followed by 20 s of rest so the response dies out. The
truth model is that of nlp/testing/four_story.py (Table 1 masses and
stiffnesses, non-proportional damping). Recorded: the table acceleration [g],
absolute accelerations of floors 1-4 [g] and LVDT displacements relative to
the table [mm], each with white sensor noise (accelerometers 2 mg rms, table
accelerometer 1 mg rms, LVDTs 0.02 mm rms). The simulation is in
nlp/testing/shake_table.py.

    python scripts/make_shake_table.py [--seed 0] [--out DIR]
"""

import argparse
import json
import os

import numpy as np

from nlp.testing.shake_table import FS, make
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "cases",
                                                  "four_story_shake_table"))
    a = ap.parse_args()
    t, cols, truth = make(a.seed)
    os.makedirs(a.out, exist_ok=True)
    names = list(cols)
    data = np.column_stack([cols[n] for n in names])
    np.savetxt(os.path.join(a.out, "records.csv"), data, delimiter=",", header=",".join(names),
               comments="", fmt=["%.3f"] + ["%.6e"] * (len(names) - 1))
    with open(os.path.join(a.out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2)
    print(f"wrote {a.out}/records.csv ({t.size} samples at {FS:g} Hz, columns {', '.join(names)})")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
