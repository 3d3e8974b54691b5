"""Each channel's own conditioning chain and calibration: a gain error (calibration
spread), an anti-alias low-pass (Butterworth, its own corner and order) and a delay.

The chain acts on the physical signal at the simulation rate, before decimation, as the
analogue conditioner and the converter do. Its frequency response (applied to a channel
that measures x, the record holds Y = G(f) X):

    G(f) = g * B_N(f; f_c) * exp(-j 2 pi f tau)

with B_N the digital Butterworth of order N at the simulation rate (scipy.signal.butter,
bilinear transform of the analogue prototype), g = 1 + calibration error, tau the delay.
An FRF estimated from two chains is H_true * G_out / G_in: it cancels only if the two
chains are identical (the blind benchmark's single filter).
"""

import numpy as np
from scipy import signal

# channel kinds and their conditioner (orders differ between conditioner types; the input
# of a shake-table test comes from the table controller's own feedback accelerometer)
ORDERS = {"acc": (4, 8), "lvdt": (2, 4), "input": (4, 6), "force": (4, 8), "base": (4, 8)}
CALIBRATION = (0.01, 0.03)   # |relative gain error| of each channel (docs/benchmarks/lab_generator.md)
CORNER = (0.36, 0.44)        # anti-alias corner / recording rate
DELAY_MS = (0.0, 0.5)        # per-channel delay [ms]: scan skew and unmodelled group delay


def kind_of(name):
    """Conditioner kind of a recorded column."""
    for k in ("acc", "lvdt", "base"):
        if name.startswith(k):
            return k
    return name if name in ORDERS else "acc"


def draw_orders(rng):
    """One filter order per conditioner kind: channels of one kind share a conditioner type."""
    return {k: int(rng.choice(np.arange(lo, hi + 1, 2))) for k, (lo, hi) in ORDERS.items()}


def draw_chain(rng, name, fs, orders, force_input=False):
    """One channel's chain: gain g (1 +- 1-3 %), its own corner f_c [Hz] (component
    tolerances), its kind's order N, delay tau [s]."""
    kind = "force" if (name == "input" and force_input) else kind_of(name)
    return {"gain": float(1 + rng.choice([-1, 1]) * rng.uniform(*CALIBRATION)),
            "corner_hz": float(rng.uniform(*CORNER) * fs),
            "order": orders[kind],
            "delay_s": float(rng.uniform(*DELAY_MS) * 1e-3)}


def butter_sos(chain, fs_sim):
    """The chain's low-pass as second-order sections at the simulation rate."""
    return signal.butter(chain["order"], chain["corner_hz"], fs=fs_sim, output="sos")


def chain_frf(chain, f, fs_sim):
    """G(f) = g B_N(f) exp(-j 2 pi f tau) (module docstring)."""
    _, B = signal.sosfreqz(butter_sos(chain, fs_sim), worN=np.asarray(f, float), fs=fs_sim)
    return chain["gain"] * B * np.exp(-2j * np.pi * np.asarray(f) * chain["delay_s"])


def delay(x, tau, fs):
    """x delayed by tau [s] (any fraction of a sample): exp(-j w tau) on the FFT of x
    zero-padded to twice its length (no wrap-around for a record that starts at rest)."""
    N = 2 * x.size
    X = np.fft.rfft(x, N)
    f = np.fft.rfftfreq(N, 1 / fs)
    return np.fft.irfft(X * np.exp(-2j * np.pi * f * tau), N)[:x.size]


def apply_chain(x, chain, fs_sim):
    """The recorded signal (before decimation) of a channel measuring x."""
    y = chain["gain"] * signal.sosfilt(butter_sos(chain, fs_sim), x)
    return delay(y, chain["delay_s"], fs_sim) if chain["delay_s"] else y
