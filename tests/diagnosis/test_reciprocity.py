"""Gain ratios from reciprocity (nlp.diagnosis.reciprocity), on two simulated tests of one
frame with the force at floor 1 and at floor 2 and the same three accelerometers."""

from types import SimpleNamespace

import math

import numpy as np
from scipy.signal import find_peaks

from nlp.diagnosis.reciprocity import gain_contradiction, reciprocal_pairs
from nlp.solve.problem import Channel

m = np.array([5.0, 4.6, 4.7])
k = np.array([52000.0, 50000.0, 48000.0])
F = np.linspace(2.0, 40.0, 1217)


def _accelerance(force_dof, rng, noise=0.005):
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    M = np.diag(m)
    C = 2e-5 * K + 0.05 * M
    b = np.eye(3)[force_dof]
    w = 2 * np.pi * F
    H = np.array([np.linalg.solve(K - wi**2 * M + 1j * wi * C, b) for wi in w]).T * -(w**2)
    return H * np.exp(noise * rng.standard_normal(H.shape))


def _test(force_dof, gains, rng):
    H = _accelerance(force_dof, rng) * (1 + np.asarray(gains))[:, None]
    chans = tuple(Channel(f"floor{i + 1}", i, "accelerance") for i in range(3))
    return SimpleNamespace(f=F, H=H, channels=chans, target=SimpleNamespace(force_dof=force_dof))


def _windows(case):
    """Points within 1.5 % of each resonance of the floor-3 channel (the fitted windows)."""
    pk, _ = find_peaks(np.abs(case.H[2]), prominence=1.0)
    return np.flatnonzero(np.any(np.abs(F[:, None] / F[pk][None, :] - 1) < 0.015, axis=1))


def test_the_ratio_of_two_sensors_gains_is_measured_without_a_model():
    rng = np.random.default_rng(4)
    g = [0.04, -0.09, 0.0]                      # floor-1 and floor-2 sensors read 4 % high, 9 % low
    a, b = _test(0, g, rng), _test(1, g, rng)
    pairs = reciprocal_pairs(a, [{"case": b, "idx": _windows(b), "label": "b"}], _windows(a))
    assert len(pairs) == 1
    p = pairs[0]
    assert (p["channel_q"], p["channel_p"]) == ("floor2", "floor1")
    truth = math.log((1 + g[1]) / (1 + g[0]))
    assert abs(p["ln_ratio"] - truth) < 3 * p["se"] and p["se"] < 0.01
    # the true gains agree with it; a gain on floor2 alone (the floor-1 sensor taken as
    # right) of the size of the ratio agrees too; one of the wrong size, or a gain on
    # floor 1 alone of the wrong sign, is refused
    assert gain_contradiction(pairs, {"floor1": g[0], "floor2": g[1]},
                              {"floor1": 0.005, "floor2": 0.005}) == ""
    assert gain_contradiction(pairs, {"floor2": math.exp(truth) - 1}, {"floor2": 0.005}) == ""
    assert "reciprocity" in gain_contradiction(pairs, {"floor2": -0.2}, {"floor2": 0.01})
    assert "reciprocity" in gain_contradiction(pairs, {"floor1": -0.1}, {"floor1": 0.01})
    # a gain on a channel no pair involves is not judged
    assert gain_contradiction(pairs, {"floor3": 0.3}, {"floor3": 0.01}) == ""


def test_tests_with_one_driving_point_fix_no_ratio():
    rng = np.random.default_rng(5)
    a, b = _test(0, [0, 0, 0], rng), _test(0, [0, 0, 0], rng)
    assert reciprocal_pairs(a, [{"case": b, "idx": _windows(b), "label": "b"}], _windows(a)) == []
