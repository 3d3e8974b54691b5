"""The effective number of independent points (nlp.diagnosis.spread.effective_points) on a
frequency grid against known correlation structures, and the spread of a mean square it
implies against simulation."""

import numpy as np

from nlp.diagnosis.spread import effective_points


def test_independent_errors_count_every_point():
    rng = np.random.default_rng(0)
    z = rng.standard_normal((4, 3000))
    n = effective_points(z, np.arange(3000))
    assert 0.9 * z.size < n < 1.1 * z.size


def test_errors_shared_by_the_channels_count_once_per_frequency():
    rng = np.random.default_rng(1)
    z = np.repeat(rng.standard_normal((1, 3000)), 5, axis=0)
    n = effective_points(z, np.arange(3000))
    assert 0.9 * 3000 < n < 1.1 * 3000


def test_implied_spread_matches_simulated_means_of_squares():
    # errors shared across 3 channels in part and smoothed over neighbouring bins (a Hann-like
    # moving average): the SD of the mean z^2 over many draws against sqrt(2 / N_eff)
    rng = np.random.default_rng(2)
    nf, nc = 200, 3

    def draw():
        common = rng.standard_normal(nf + 2)
        own = rng.standard_normal((nc, nf + 2))
        e = 0.8 * common + 0.6 * own
        return (e[:, :-2] + 2 * e[:, 1:-1] + e[:, 2:]) / np.sqrt(6.0)

    means = [np.mean(draw() ** 2) for _ in range(2000)]
    n = np.median([effective_points(draw(), np.arange(nf)) for _ in range(50)])
    implied = np.sqrt(2.0 / n)
    assert 0.85 * implied < np.std(means) < 1.15 * implied
