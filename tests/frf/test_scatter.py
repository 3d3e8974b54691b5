"""Scatter noise of a windowed FRF estimate (nlp.frf.scatter.local_scatter) against the truth."""

import numpy as np
from scipy import signal

from nlp.frf.scatter import local_scatter, second_difference_factor


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


def test_bins_three_apart_are_uncorrelated_for_hann():
    from nlp.frf.scatter import correlation_lag
    # w^2 of Hann holds cos x and cos 2x only, so c_l = 0 from l = 3 on
    assert correlation_lag("hann") == 3
    assert correlation_lag("none") == 1
    assert correlation_lag("blackman") == 5


def _hann_bins(rng, n_seg, n_bins, leakage):
    """ln|H| errors of a Hann-windowed estimate, unit variance, along n_bins bins.

    The windowed DFT of white noise is the white DFT smoothed by (-1/4, 1/2, -1/4).
    Output noise enters H1 as sum X* N / sum |X|^2 (over n_seg segments): bins
    correlate as |c_l|^2 (4/9 at lag 1). Leakage of a response that outlasts the
    segment is a smooth term times one windowed spectrum: bins correlate as c_l
    itself (-2/3 at lag 1)."""
    taps = np.array([-0.25, 0.5, -0.25])

    def windowed():
        z = rng.standard_normal((n_seg, n_bins + 2)) + 1j * rng.standard_normal((n_seg, n_bins + 2))
        return (taps[0] * z[:, :-2] + taps[1] * z[:, 1:-1] + taps[2] * z[:, 2:]) / np.sqrt(0.375 * 2)

    if leakage:
        e = windowed()[0].real
    else:
        x, nn = windowed(), windowed()
        e = (np.sum(np.conj(x) * nn, axis=0) / np.sum(np.abs(x) ** 2, axis=0)).real
    return e / np.std(e)


def test_spaced_scatter_reads_leakage_and_noise_alike():
    """Errors of unit sd either way: adjacent second differences (factor 2.5 for Hann
    noise) read leakage-type errors sqrt(11.67 / 2.5) = 2.2 x too large; third
    differences of bins three apart read both as they are."""
    from nlp.frf.scatter import spaced_scatter
    rng = np.random.default_rng(4)
    f = np.arange(4000) * 0.01
    for leakage in (False, True):
        e = _hann_bins(rng, 16, f.size, leakage)
        H = np.exp(e)[None] * (1.0 + 0j)
        sp = np.median(spaced_scatter(f, H, window="hann")[0])
        adj = np.median(local_scatter(f, H, window="hann")[0])
        assert abs(sp - 1) < 0.1, (leakage, sp)
        if leakage:
            expect = np.sqrt((6 + 8 * 2 / 3 + 2 / 6) / 2.5)
            assert abs(adj / expect - 1) < 0.12, (adj, expect)
        else:
            assert abs(adj - 1) < 0.1, adj


def test_spaced_scatter_of_pure_noise_needs_no_window_factor():
    from nlp.frf.scatter import spaced_scatter
    rng = np.random.default_rng(3)
    fs, n = 100.0, 2 ** 17
    x = rng.standard_normal(n)
    y = 2.0 * x + 0.3 * rng.standard_normal(n)
    kw = dict(fs=fs, window="hann", nperseg=512, noverlap=256)
    f, sxy = signal.csd(x, y, **kw)
    _, sxx = signal.welch(x, **kw)
    H1 = (sxy / sxx)[None, 5:-5]
    actual = np.std(np.log(np.abs(H1[0]) / 2.0))
    est = np.median(spaced_scatter(f[5:-5], H1, window="hann")[0])
    assert abs(est / actual - 1) < 0.12, (est, actual)
