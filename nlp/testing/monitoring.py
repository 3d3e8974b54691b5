"""A monitoring campaign simulated independently of the package's FRF code: FRF records
of the paper's four-storey frame over weeks.

Its story stiffnesses follow the temperature (a daily cycle, day-to-day weather and a
slow warming: about +-1.5 %), and story 2 loses `drop` of its stiffness at record
`change` (damage). Each record carries 1 % log-normal magnitude noise and 0.6 degree
phase noise. The FRFs are computed here with plain numpy (a direct solve of the dynamic
stiffness per frequency), so the identification is checked against an independent
simulator.
"""

import datetime as dt
import json
import os

import numpy as np

from nlp.testing.four_story import MASSES
from nlp.testing.four_story import STIFFNESSES as STIFF   # N/m, undamaged, at 10 degC
from nlp.testing.frames import shear_K

ZETA = 0.02                                           # Rayleigh, at modes 1 and 4


def absolute_accelerance(m, k, zeta, f):
    """Absolute floor acceleration per unit base acceleration, direct solve per frequency."""
    M, K = np.diag(m), shear_K(k)
    lam = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    w1, w4 = np.sqrt(lam[0]), np.sqrt(lam[-1])
    a1 = 2 * zeta / (w1 + w4)            # Rayleigh C = a0 M + a1 K, zeta at w1 and w4
    a0 = a1 * w1 * w4
    C = a0 * M + a1 * K
    ones = np.ones(m.size)
    H = np.empty((m.size, f.size), complex)
    for i, w in enumerate(2 * np.pi * f):
        x_rel = np.linalg.solve(K - w**2 * M + 1j * w * C, -M @ ones)
        H[:, i] = 1.0 - w**2 * x_rel     # absolute = base + relative acceleration
    return H


def write_campaign(out, seed=0, records=120, change=80, drop=0.08, hours_between=6.0):
    """Write out/records/rec_###_<time stamp>.npz (f [Hz], H (4, n_f) absolute accelerance,
    timestamp ISO 8601) and out/truth.json; returns the records folder."""
    rng = np.random.default_rng(seed)
    f = np.arange(0.5, 8.0 + 1e-9, 0.02)
    t0 = dt.datetime(2026, 1, 5, 0, 0)
    rec_dir = os.path.join(out, "records")
    os.makedirs(rec_dir, exist_ok=True)
    for name in os.listdir(rec_dir):
        if name.endswith(".npz"):
            os.unlink(os.path.join(rec_dir, name))
    truth = {"seed": seed, "change_record": change, "drop": drop, "story": 2,
             "records": []}
    weather = 0.0
    for i in range(records):
        hours = i * hours_between
        weather = 0.9 * weather + 0.5 * rng.standard_normal()   # day-to-day, about +-1 degC
        temp = 10 + 4 * np.sin(2 * np.pi * (hours - 8) / 24) + 3 * hours / (24 * 30) + weather
        k = STIFF * (1 - 0.0025 * (temp - 10))       # steel/aluminium soften when warm
        if i >= change:
            k = k * np.array([1, 1 - drop, 1, 1])
        H = absolute_accelerance(MASSES, k, ZETA, f)
        noise = np.exp(0.01 * rng.standard_normal(H.shape)
                       + 1j * np.deg2rad(0.6) * rng.standard_normal(H.shape))
        stamp = (t0 + dt.timedelta(hours=hours)).strftime("%Y-%m-%dT%H:%M")
        fname = f"rec_{i:03d}_{stamp.replace(':', '')}.npz"
        np.savez_compressed(os.path.join(rec_dir, fname), f=f, H=(H * noise).astype(np.complex64),
                            timestamp=stamp)
        truth["records"].append({"file": fname, "timestamp": stamp, "temperature": round(temp, 3),
                                 "stiffnesses": k.round(4).tolist()})
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    return rec_dir
