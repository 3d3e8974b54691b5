"""Spike and dropout screening against known injected glitches."""

import numpy as np

from nlp.io.quality import detect_glitches, screen_records


def _signal(n=8000, fs=200.0):
    """Oversampled broadband response: sum of sines 1-15 Hz plus 0.1 % white noise."""
    rng = np.random.default_rng(2)
    t = np.arange(n) / fs
    x = sum(np.sin(2 * np.pi * f * t + p) / f for f, p in zip(rng.uniform(1, 15, 12),
                                                                   rng.uniform(0, 6, 12)))
    return x + 1e-3 * np.std(x) * rng.normal(size=n)


def test_clean_record_has_no_glitches():
    assert detect_glitches(_signal()) == []


def test_isolated_adjacent_and_near_spikes_found_and_repaired():
    clean = _signal()
    x = clean.copy()
    s = 3 * np.std(clean)
    spikes = [500, 1500, 1501, 2500, 2502, 4000]  # alone, side by side, two apart
    for k, i in enumerate(spikes):
        x[i] += s if k % 2 else -s
    x[6000:6012] = 0.0  # a dropout
    found = detect_glitches(x)
    flagged = {i for kind, a, b in found if kind == "spike" for i in range(a, b)}
    assert flagged == set(spikes)
    assert [(k, a, b) for k, a, b in found if k == "dropout"] == [("dropout", 6000, 6012)]
    fixed, rep = screen_records({"a": x}, 200.0, remove=True)
    assert rep.counts()["a"] == {"spikes": 5, "dropouts": 1, "samples_flagged": 18,
                                 "fraction_flagged": 18 / x.size}
    err = np.abs(fixed["a"] - clean)
    assert err[np.r_[spikes]].max() < 0.01 * s          # spline through good samples
    assert err[6000:6012].max() < 0.15 * np.std(clean)  # 60 ms gap: a close guess
    unchanged, rep2 = screen_records({"a": x}, 200.0, remove=False)
    assert unchanged["a"] is x and not rep2.removed
