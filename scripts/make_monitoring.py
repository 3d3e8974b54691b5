"""Simulate a monitoring campaign: FRF records of one frame over weeks.

Writes ``cases/monitoring/records/rec_###_<time stamp>.npz`` (arrays ``f`` [Hz],
``H`` (4, n_f) absolute accelerance [(m/s^2)/(m/s^2)] of floors 1-4 under base
acceleration, ``timestamp`` ISO 8601), ``truth.json`` (read only by checks,
never by the updater) and leaves ``case.yaml`` as it is.

The structure is the paper's four-storey shear frame. Its story stiffnesses
follow the temperature (a daily cycle, day-to-day weather and a slow warming:
about +-1.5 %), and story 2 loses ``--drop`` of its stiffness at record ``--change``
(damage). Each record carries 1 % log-normal magnitude noise and 0.6 degree
phase noise.

The FRFs are computed here with plain numpy (a direct solve of the dynamic
stiffness per frequency): nothing of the package is imported, so the
identification is checked against an independent simulator.

    python scripts/make_monitoring.py --seed 0
"""

import argparse
import datetime as dt
import json
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "monitoring")

MASSES = np.array([5.16, 5.15, 4.94, 5.14])          # kg (weighed, fixed in the case)
STIFF = np.array([1054.98, 1284.19, 1377.13, 2738.17])  # N/m, undamaged, at 10 degC
ZETA = 0.02                                           # Rayleigh, at modes 1 and 4


def shear_K(k):
    n = k.size
    K = np.zeros((n, n))
    for r in range(n):
        K[r, r] += k[r]
        if r:
            K[r - 1, r - 1] += k[r]
            K[r - 1, r] -= k[r]
            K[r, r - 1] -= k[r]
    return K


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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--records", type=int, default=120)
    ap.add_argument("--change", type=int, default=80, help="first damaged record (0-based)")
    ap.add_argument("--drop", type=float, default=0.08, help="relative stiffness loss of story 2")
    ap.add_argument("--hours", type=float, default=6.0, help="time between records")
    ap.add_argument("--out", default=CASE)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    f = np.arange(0.5, 8.0 + 1e-9, 0.02)
    t0 = dt.datetime(2026, 1, 5, 0, 0)
    rec_dir = os.path.join(a.out, "records")
    os.makedirs(rec_dir, exist_ok=True)
    for name in os.listdir(rec_dir):
        if name.endswith(".npz"):
            os.unlink(os.path.join(rec_dir, name))
    truth = {"seed": a.seed, "change_record": a.change, "drop": a.drop, "story": 2,
             "records": []}
    weather = 0.0
    for i in range(a.records):
        hours = i * a.hours
        weather = 0.9 * weather + 0.5 * rng.standard_normal()   # day-to-day, about +-1 degC
        temp = 10 + 4 * np.sin(2 * np.pi * (hours - 8) / 24) + 3 * hours / (24 * 30) + weather
        k = STIFF * (1 - 0.0025 * (temp - 10))       # steel/aluminium soften when warm
        if i >= a.change:
            k = k * np.array([1, 1 - a.drop, 1, 1])
        H = absolute_accelerance(MASSES, k, ZETA, f)
        noise = np.exp(0.01 * rng.standard_normal(H.shape)
                       + 1j * np.deg2rad(0.6) * rng.standard_normal(H.shape))
        stamp = (t0 + dt.timedelta(hours=hours)).strftime("%Y-%m-%dT%H:%M")
        fname = f"rec_{i:03d}_{stamp.replace(':', '')}.npz"
        np.savez_compressed(os.path.join(rec_dir, fname), f=f, H=(H * noise).astype(np.complex64),
                            timestamp=stamp)
        truth["records"].append({"file": fname, "timestamp": stamp, "temperature": round(temp, 3),
                                 "stiffnesses": k.round(4).tolist()})
    with open(os.path.join(a.out, "truth.json"), "w") as fh:
        json.dump(truth, fh, indent=1)
    print(f"wrote {a.records} records to {rec_dir} (story 2 -{100 * a.drop:.0f} % "
          f"from record {a.change})")


if __name__ == "__main__":
    main()
