"""Are the lab benchmark's sensor-delay findings the conditioning chains' group delay?

The lab generator (nlp/testing/lab/chain.py) gives every channel its own anti-alias
Butterworth (order by conditioner kind, corner 0.36-0.44 of the recording rate) and a delay
under 0.5 ms. An FRF is H G_out / G_in, so a channel whose filter differs from the input's
carries their differential group delay: at low frequency a Butterworth of order N and corner
w_c delays by 1 / (w_c sin(pi / 2N)), several ms at the rates of these cases. This prints,
for every channel of each scored case, the delay `diagnose` read from the phase
(`phase_check`) beside the slope of the truth's arg(G_out / G_in) over the fitted band.

    python research/chain_delays.py BENCH [CASE ...]
"""

import argparse
import json
import os

import numpy as np
from scipy import signal

KINDS = {"a": "acc", "d": "lvdt"}


def chain_phase(chain, w):
    """arg G(j w) of one chain [rad]: its analogue Butterworth and its delay."""
    b, a = signal.butter(chain["order"], 2 * np.pi * chain["corner_hz"], analog=True)
    _, h = signal.freqs(b, a, worN=w)
    return np.unwrap(np.angle(h)) - w * chain["delay_s"]


def chain_delay_ms(chains, channel, f):
    """The delay [ms] of channel's FRF from its chain against the input's, fitted over f."""
    key = KINDS.get(channel[0], "acc") + channel[1:]
    if key not in chains:
        return None
    w = 2 * np.pi * np.asarray(f, float)
    d = chain_phase(chains[key], w) - chain_phase(chains["input"], w)
    return -1e3 * np.polyfit(w, d, 1)[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bench")
    ap.add_argument("cases", nargs="*")
    a = ap.parse_args()
    cases = a.cases or sorted(c for c in os.listdir(a.bench)
                              if os.path.isfile(os.path.join(a.bench, c, "truth.json")))
    for case in cases:
        path = os.path.join(a.bench, case, "diagnosis", "diagnosis.json")
        if not os.path.isfile(path):
            continue
        with open(path) as fh:
            d = json.load(fh)
        with open(os.path.join(a.bench, case, "truth.json")) as fh:
            chains = json.load(fh)["lab"]["chains"]
        span = d.get("mismatch_left", {}) or {}
        lo, hi = span.get("fitted_band_hz") or (1.0, 15.0)
        f = np.linspace(max(lo, 0.1), hi, 60)
        named = {f_["location"]["channel"] for f_ in d["findings"] if f_["physics"] == "sensor_delay"}
        print(case)
        for r in d.get("phase_check") or []:
            want = chain_delay_ms(chains, r["channel"], f)
            if want is None:
                continue
            print(f"  {r['channel']:4s} read {r['delay_ms']:7.2f} +- {r['standard_error_ms']:.2f} ms, "
                  f"chains {want:7.2f} ms{'  (named)' if r['channel'] in named else ''}")


if __name__ == "__main__":
    main()
