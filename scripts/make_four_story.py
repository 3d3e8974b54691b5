"""Make the simulated data of cases/four_story_shear_frame from a seed.

Truth: the masses and stiffnesses of Table 1's "Average of the updated" row
and a non-proportional damping matrix (Rayleigh plus two local dashpots).
Data: ground-acceleration receptance FRFs of all four floors on 0.02-12 Hz
with 2 % complex Gaussian noise (relative to |H| at each point); the model
and the simulation are in nlp/testing/four_story.py.

    python scripts/make_four_story.py [--seed 0] [--noise 0.02] [--out DIR]
"""

import argparse
import json
import os

import numpy as np

from nlp.testing.four_story import make
from nlp.solve.executors.threads import limit_blas_threads


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "..", "cases",
                                                  "four_story_shear_frame"))
    a = ap.parse_args()
    f, H, truth = make(a.seed, a.noise)
    os.makedirs(a.out, exist_ok=True)
    np.savez(os.path.join(a.out, "frf.npz"), f=f, H=H)
    with open(os.path.join(a.out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=2)
    print(f"wrote {a.out}/frf.npz ({H.shape[0]} channels x {f.size} points) and truth.json; "
          f"natural frequencies {np.round(truth['natural_frequencies_hz'], 3)} Hz")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
