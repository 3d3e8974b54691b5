"""Pairing of measured peaks with nominal modes, and the points kept for modes no peak shows."""

import numpy as np

from nlp.frf.freqsel import MATCH_RATIO, match_modes, unresolved_points


def test_pairs_keep_order_and_skip_the_mode_no_peak_shows():
    model = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    peaks = np.array([1.05, 2.1, 4.2, 5.25])        # the third mode is not found
    assert match_modes(peaks, model) == [(0, 0), (1, 1), (2, 3), (3, 4)]


def test_no_pair_further_apart_than_the_ratio():
    assert match_modes([1.0], [1.0 * MATCH_RATIO * 1.01]) == []
    assert match_modes([1.0], [1.0 * MATCH_RATIO * 0.99]) == [(0, 0)]


def test_a_shifted_spectrum_pairs_by_order_not_by_nearest():
    # every model mode 10 % low: the nearest model mode of peak i + 1 is still mode i + 1
    model = np.array([1.0, 1.2, 1.44, 1.728])
    assert match_modes(model * 1.1, model) == [(i, i) for i in range(4)]


def test_unresolved_mode_keeps_every_point_between_its_neighbours():
    f = np.linspace(0.5, 6.0, 551)
    model = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    peaks = np.array([1.05, 2.1, 4.2, 5.25])
    idx = unresolved_points(f, peaks, model)
    assert np.isclose(f[idx].min(), 2.1) and np.isclose(f[idx].max(), 4.2)
    assert unresolved_points(f, model[1:] * 1.05, model[1:]).size == 0  # every mode found
    # a missing lowest mode: from the band's start to the first paired peak
    idx = unresolved_points(f, np.array([2.1, 3.15]), np.array([1.0, 2.0, 3.0]))
    assert f[idx].min() == f[0] and np.isclose(f[idx].max(), 2.1)
