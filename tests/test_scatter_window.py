"""Scatter noise of a windowed FRF estimate (nlp.noise.local_scatter) against the truth."""

import numpy as np
from scipy import signal

from nlp.noise import local_scatter, second_difference_factor


def test_hann_factor_from_the_window_transform():
    # c_1 = -2/3 and c_2 = 1/6 for Hann (its w^2 = (3 - 4 cos + cos 2x) / 8)
    assert abs(second_difference_factor("hann") - (6 - 8 * 4 / 9 + 2 / 36)) < 1e-3
    assert second_difference_factor("boxcar") == 6.0


def test_scatter_of_a_welch_h1_matches_its_actual_error():
    rng = np.random.default_rng(2)
    fs, n = 100.0, 2 ** 17
    x = rng.standard_normal(n)
    y = 2.0 * x + 0.3 * rng.standard_normal(n)    # H = 2 at every frequency
    kw = dict(fs=fs, window="hann", nperseg=512, noverlap=256)
    f, sxy = signal.csd(x, y, **kw)
    _, sxx = signal.welch(x, **kw)
    H1 = (sxy / sxx)[None, 5:-5]
    err = np.log(np.abs(H1[0]) / 2.0)
    actual = np.std(err)
    for window, close in (("hann", True), (None, False)):
        est = np.median(local_scatter(f[5:-5], H1, window=window)[0])
        if close:
            assert abs(est / actual - 1) < 0.12
        else:
            # independent-point scatter misses the bins' correlation by sqrt(6 / 2.5)
            assert est / actual < 0.75
