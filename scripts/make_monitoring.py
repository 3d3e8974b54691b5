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

The FRFs are computed with plain numpy (a direct solve of the dynamic
stiffness per frequency, nlp/testing/monitoring.py): nothing of the package's
FRF code is used, so the identification is checked against an independent
simulator.

    python scripts/make_monitoring.py --seed 0
"""

import argparse
import os

from nlp.testing.monitoring import write_campaign
from nlp.solve.executors.threads import limit_blas_threads

HERE = os.path.dirname(os.path.abspath(__file__))
CASE = os.path.join(HERE, "..", "cases", "monitoring")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--records", type=int, default=120)
    ap.add_argument("--change", type=int, default=80, help="first damaged record (0-based)")
    ap.add_argument("--drop", type=float, default=0.08, help="relative stiffness loss of story 2")
    ap.add_argument("--hours", type=float, default=6.0, help="time between records")
    ap.add_argument("--out", default=CASE)
    a = ap.parse_args()
    rec_dir = write_campaign(a.out, a.seed, a.records, a.change, a.drop, a.hours)
    print(f"wrote {a.records} records to {rec_dir} (story 2 -{100 * a.drop:.0f} % "
          f"from record {a.change})")


if __name__ == "__main__":
    limit_blas_threads()  # as the frf-nlp command does (nlp/solve/executors/threads.py)
    main()
