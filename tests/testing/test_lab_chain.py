"""The lab's conditioning chains and calibration (nlp/testing/lab/chain.py) against the
analytic low-pass x delay response, and the gains' ratio in an estimated FRF."""

import numpy as np
from scipy import signal

from nlp.testing.lab.chain import apply_chain, chain_frf, delay, draw_chain, draw_orders

FS = 2000.0


def _sine_response(chain, f, seconds=6.0):
    """Amplitude and phase of the chain's steady response to sin(2 pi f t), by least
    squares on the middle of the record (away from the start and the delay's edges)."""
    t = np.arange(0, seconds, 1 / FS)
    y = apply_chain(np.sin(2 * np.pi * f * t), chain, FS)
    mid = (t > 2.0) & (t < seconds - 2.0)
    A = np.column_stack([np.sin(2 * np.pi * f * t[mid]), np.cos(2 * np.pi * f * t[mid])])
    s, c = np.linalg.lstsq(A, y[mid], rcond=None)[0]
    return s + 1j * c            # y = Im(G e^{jwt}) = Re(G) sin + Im(G) cos


def test_chain_response_is_gain_times_butterworth_times_delay():
    a = {"gain": 1.02, "corner_hz": 41.0, "order": 2, "delay_s": 0.37e-3}
    b = {"gain": 0.985, "corner_hz": 38.0, "order": 8, "delay_s": 0.05e-3}
    for f in (1.3, 7.0, 19.0, 30.0):
        for ch in (a, b):
            # analytic: |B_N| of the analogue prototype at the prewarped frequency
            wa = np.tan(np.pi * f / FS) / np.tan(np.pi * ch["corner_hz"] / FS)
            mag = ch["gain"] / np.sqrt(1 + wa ** (2 * ch["order"]))
            G = _sine_response(ch, f)
            assert abs(abs(G) - mag) < 1e-3 * mag
            assert abs(G - chain_frf(ch, [f], FS)[0]) < 1e-3 * mag
        # the ratio of two channels' chains: what an FRF between them carries
        ratio = _sine_response(b, f) / _sine_response(a, f)
        expect = chain_frf(b, [f], FS)[0] / chain_frf(a, [f], FS)[0]
        assert abs(ratio - expect) < 2e-3 * abs(expect)


def test_fractional_delay_is_exact_on_a_band_limited_pulse():
    t = np.arange(0, 4, 1 / FS)
    x = np.exp(-((t - 1.0) / 0.05) ** 2)
    tau = 0.7 / FS + 1.3e-3
    y = delay(x, tau, FS)
    assert np.max(np.abs(y - np.exp(-((t - 1.0 - tau) / 0.05) ** 2))) < 1e-9


def test_the_calibration_factors_appear_in_H_as_their_ratio():
    rng = np.random.default_rng(5)
    x = rng.standard_normal(2**16)
    b_, a_ = signal.butter(2, 60.0, fs=FS)              # some physical response y = h * x
    y = signal.lfilter(b_, a_, x)
    same = {"corner_hz": 800.0, "order": 4, "delay_s": 0.0}
    cin, cout = dict(same, gain=0.98), dict(same, gain=1.025)
    xm, ym = apply_chain(x, cin, FS), apply_chain(y, cout, FS)
    f, sxx = signal.welch(xm, FS, nperseg=4096)
    _, sxy = signal.csd(xm, ym, FS, nperseg=4096)
    band = (f > 2) & (f < 100)
    H_true = signal.freqz(b_, a_, worN=f[band], fs=FS)[1]
    ratio = (sxy / sxx)[band] / H_true
    assert np.allclose(np.median(ratio.real), 1.025 / 0.98, rtol=2e-3)
    assert np.max(np.abs(ratio.imag)) < 5e-3


def test_drawn_chains_stay_in_the_stated_ranges_and_differ_between_channels():
    rng = np.random.default_rng(0)
    orders = draw_orders(rng)
    chains = [draw_chain(rng, name, 100.0, orders) for name in ("input", "acc1", "acc2", "lvdt1")]
    for c in chains:
        assert 0.01 <= abs(c["gain"] - 1) <= 0.03
        assert 36.0 <= c["corner_hz"] <= 44.0 and 0.0 <= c["delay_s"] <= 0.5e-3
    assert len({round(c["corner_hz"], 6) for c in chains}) == len(chains)
    assert chains[1]["order"] == chains[2]["order"] == orders["acc"]     # one conditioner type
