"""Write the Cristallo frame's FRFs as a magnitude-only dB export (no phase), laid out the
way a spectrum analyser exports them: a commented preamble, a header line with units and
the dB reference, tab-separated columns, 4 decimals.

    python scripts/make_cristallo_magnitude.py   # writes cases/cristallo_three_storey_magnitude/
"""

import os

import numpy as np

from nlp.io.readers import read_frf
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(HERE, "..", "cases", "cristallo_three_storey", "Experimental.csv")
OUT = os.path.join(HERE, "..", "cases", "cristallo_three_storey_magnitude", "Experimental_dB.txt")
FMAX = 64.0  # Hz; the case fits 4-40 Hz


def main():
    f, H = read_frf(SRC, fmt="complex")
    keep = f <= FMAX
    db = 20 * np.log10(np.abs(H[:, keep]))
    lines = ["% Cristallo three-storey frame, run 'Experimental' (force at floor 1)",
             "% Magnitude only: 20 log10 |H|, dB re 1 (m/s^2)/N",
             "Frequency [Hz]\tFloor 1 [dB]\tFloor 2 [dB]\tFloor 3 [dB]"]
    lines += ["\t".join([f"{fi:.5f}"] + [f"{v:.4f}" for v in row])
              for fi, row in zip(f[keep], db.T)]
    with open(OUT, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"wrote {OUT}: {keep.sum()} frequencies, 3 channels")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
