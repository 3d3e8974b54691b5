"""Simulate the paper's shake-table test (Section 4.1) on the four-story frame.

Ground motion: a linear chirp from 0 to 10 Hz in 60 s, 1 m/s^2 amplitude,
sampled at 200 Hz, followed by 20 s of rest so the response dies out. The
truth model is that of scripts/make_four_story.py (Table 1 masses and
stiffnesses, non-proportional damping). Recorded: the table acceleration [g],
absolute accelerations of floors 1-4 [g] and LVDT displacements relative to
the table [mm], each with white sensor noise (accelerometers 2 mg rms, table
accelerometer 1 mg rms, LVDTs 0.02 mm rms).

    python scripts/make_shake_table.py [--seed 0] [--out DIR]
"""

import argparse
import json
import os

import numpy as np
from scipy.signal import chirp

from make_four_story import MASSES, STIFFNESSES, true_damping
from nlp.frf.reference import modal_parameters
from nlp.model.nominal import shear_stiffness
from nlp.frf.simulate import simulate

G = 9.80665
FS = 200.0


def make(seed=0):
    """Return (t, columns dict in file units, truth dict)."""
    t = np.arange(0, 80.0, 1 / FS)
    ag = np.where(t <= 60.0, chirp(t, f0=0.0, t1=60.0, f1=10.0, method="linear"), 0.0)
    ag *= np.sin(np.pi * np.clip(t / 60.0, 0, 1)) ** 0.1  # soft start and end
    M, K = np.diag(MASSES), shear_stiffness(STIFFNESSES)
    C = true_damping(M, K)
    resp = simulate(M, C, K, ag, FS, input="ground")
    rng = np.random.default_rng(seed)
    cols = {"t": t, "ag": (ag + 0.001 * G * rng.standard_normal(t.size)) / G}
    for i in range(4):
        cols[f"acc{i + 1}"] = (resp.a[i] + 0.002 * G * rng.standard_normal(t.size)) / G
    for i in range(4):
        cols[f"lvdt{i + 1}"] = 1e3 * resp.q[i] + 0.02 * rng.standard_normal(t.size)
    fn, zeta, _ = modal_parameters(M, C, K)
    truth = {"masses": MASSES.tolist(), "stiffnesses": STIFFNESSES.tolist(), "C": C.tolist(),
             "natural_frequencies_hz": fn.tolist(), "damping_ratios": zeta.tolist(), "seed": seed,
             "noise": {"table_acc_g": 0.001, "acc_g": 0.002, "lvdt_mm": 0.02}}
    return t, cols, truth


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
    main()
