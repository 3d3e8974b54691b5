"""Coloured common-mode noise (nlp/testing/lab/noise.py): the stated cross-channel
correlation within its derived sampling SD, and the 1/f slope."""

import numpy as np

from nlp.testing.lab.noise import coloured, correlation_sd, lab_noise, shape


def test_common_mode_share_is_the_cross_channel_correlation():
    n, fs = 2**15, 200.0
    for c, pink in ((0.3, 0.0), (0.45, 0.6)):
        for seed in range(3):
            rng = np.random.default_rng(seed)
            z = lab_noise(rng, ["a", "b", "c"], n, fs, {"a": 1.0, "b": 2.0, "c": 0.1}, c, pink)
            sd = correlation_sd(n, fs, pink, c)
            for p, q in (("a", "b"), ("a", "c"), ("b", "c")):
                r = np.corrcoef(z[p], z[q])[0, 1]
                assert abs(r - c) < 4 * sd, (c, pink, r, sd)
    # the derived SD is the white-noise one, (1 - c^2)/sqrt(n), for white noise
    assert np.isclose(correlation_sd(n, fs, 0.0, 0.3), (1 - 0.09) / np.sqrt(n), rtol=0.01)


def test_the_sampling_sd_is_what_repeated_draws_show():
    n, fs, c, pink = 4096, 100.0, 0.3, 0.6
    rs = [np.corrcoef(*[v for v in lab_noise(np.random.default_rng(s), ["a", "b"], n, fs,
                                               {"a": 1.0, "b": 1.0}, c, pink).values()])[0, 1]
          for s in range(200)]
    # SD of an SD estimate from 200 draws: about 5 %; allow 25 %
    assert abs(np.std(rs) / correlation_sd(n, fs, pink, c) - 1) < 0.25


def test_pink_part_falls_as_one_over_f_and_white_part_is_flat():
    n, fs = 2**18, 200.0
    rng = np.random.default_rng(1)
    x = coloured(rng, n, fs, 1.0)
    P = np.abs(np.fft.rfft(x)) ** 2
    f = np.fft.rfftfreq(n, 1 / fs)
    edges = np.geomspace(0.2, 80.0, 9)
    mids = np.sqrt(edges[:-1] * edges[1:])
    level = [P[(f >= lo) & (f < hi)].mean() for lo, hi in zip(edges[:-1], edges[1:])]
    slope = np.polyfit(np.log(mids), np.log(level), 1)[0]
    assert abs(slope + 1) < 0.1
    assert np.isclose(np.std(x), 1.0)
    s = shape(np.array([1.0, 10.0, 50.0]), fs, 0.0)
    assert np.allclose(s, s[0])
