"""The paper's shake-table test (Section 4.1) simulated on the four-story frame.

Ground motion: a linear chirp from 0 to 10 Hz in 60 s, 1 m/s^2 amplitude, sampled at
200 Hz, followed by 20 s of rest so the response dies out. The truth model is that of
`nlp.testing.four_story` (Table 1 masses and stiffnesses, non-proportional damping).
Recorded: the table acceleration [g], absolute accelerations of floors 1-4 [g] and LVDT
displacements relative to the table [mm], each with white sensor noise (accelerometers
2 mg rms, table accelerometer 1 mg rms, LVDTs 0.02 mm rms).

The response comes from the package's `nlp.frf.simulate`: these records check the
time-history route and the workflow, not the integrator (its own tests compare it with
scipy.signal.lsim and the exact FRF).
"""

import numpy as np
from scipy.signal import chirp

from nlp.frf.reference import modal_parameters
from nlp.frf.simulate import simulate
from nlp.model.nominal import shear_stiffness
from nlp.testing.four_story import MASSES, STIFFNESSES, true_damping

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
