"""Peak finding, half-power bands and frequency-point selection on an exact 3-DOF FRF."""

import numpy as np
import pytest
from scipy import linalg, signal

from nlp.errors import InputError
from nlp.frf.freqsel import find_peaks, half_power_band, plot_selection, select_frequencies

ZETA = np.array([0.01, 0.015, 0.008])
DF = 0.002  # Hz


def _system():
    """3-DOF shear frame with exact modal damping ZETA (C = M Phi diag(2 zeta w) Phi^T M)."""
    m = np.array([2.0, 1.5, 1.0])
    k = np.array([1000.0, 750.0, 500.0])
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    lam, phi = linalg.eigh(K, M)  # mass-normalised modes
    wn = np.sqrt(lam)
    C = M @ phi @ np.diag(2 * ZETA * wn) @ phi.T @ M
    return M, C, K, wn / (2 * np.pi)


@pytest.fixture(scope="module")
def frf():
    """Receptances of all floors to a force at the top floor, f in Hz."""
    M, C, K, fn = _system()
    f = np.arange(0.05, 10.0, DF)
    w = 2 * np.pi * f
    H = np.array([np.linalg.solve(K - wi**2 * M + 1j * wi * C, [0, 0, 1.0]) for wi in w]).T
    return f, H, fn


def test_peaks_at_natural_frequencies(frf):
    f, H, fn = frf
    idx = find_peaks(f, H)
    assert idx.size == 3 and np.all(np.diff(idx) > 0)
    # the damped peak sits fn * sqrt(1 - 2 zeta^2) ~ fn: within a grid step
    np.testing.assert_array_less(np.abs(f[idx] - fn), DF + 1e-12)


def test_find_peaks_limits(frf):
    f, H, fn = frf
    assert f[find_peaks(f, H, fmin=3.0)] == pytest.approx(f[find_peaks(f, H)[1:]])
    assert find_peaks(f, H, fmax=3.0).size == 1
    # the most prominent single peak of the sum of receptances is the first mode
    assert np.abs(f[find_peaks(f, H, n_peaks=1)][0] - fn[0]) <= DF
    assert find_peaks(f, H, prominence_db=200.0).size == 0


def test_half_power_bandwidth_gives_modal_damping(frf):
    f, H, fn = frf
    mag = np.abs(H).sum(axis=0)
    for ip, fr, zeta in zip(find_peaks(f, H), fn, ZETA):
        f_lo, f_hi = half_power_band(f, mag, ip)
        assert f_lo < fr < f_hi
        assert (f_hi - f_lo) / (2 * fr) == pytest.approx(zeta, rel=0.03)


def test_half_power_band_hand_example():
    # triangle 0, 2, 4, 2, 0 on f = 0..4: level 4/sqrt2 = 2.828 crossed at 2 -/+ 0.586
    f = np.arange(5.0)
    lo, hi = half_power_band(f, np.array([0, 2, 4, 2, 0.0]), 2)
    assert lo == pytest.approx(2 - (4 - 4 / np.sqrt(2)) / 2)
    assert hi == pytest.approx(2 + (4 - 4 / np.sqrt(2)) / 2)
    # starting on the flank climbs to the peak; a side that never falls is NaN
    lo, hi = half_power_band(f, np.array([1, 2, 4, 3.5, 3.9]), 1)
    assert lo == pytest.approx(1.0 + (4 / np.sqrt(2) - 2) / 2) and np.isnan(hi)


def test_selection_follows_half_power_bands(frf):
    f, H, fn = frf
    for k in (0.5, 1.0, 2.0):
        idx = select_frequencies(f, H, k=k)
        chosen = np.zeros(f.size, bool)
        chosen[idx] = True
        near = np.zeros(f.size, bool)
        for fr, zeta in zip(fn, ZETA):
            half = k * 2 * zeta * fr  # k times the true half-power bandwidth
            assert chosen[np.abs(f - fr) <= 0.95 * half].all()
            near |= np.abs(f - fr) <= 1.05 * half + DF
        assert not chosen[~near].any()


def test_min_points_per_peak_on_coarse_grid(frf):
    _, _, fn = frf
    M, C, K, _ = _system()
    f = np.arange(0.1, 10.0, 0.05)  # coarser than the half-power bands
    w = 2 * np.pi * f
    H = np.array([np.linalg.solve(K - wi**2 * M + 1j * wi * C, [0, 0, 1.0]) for wi in w]).T
    idx = select_frequencies(f, H, k=0.5, min_points_per_peak=5)
    for fr in fn:
        nearest5 = np.argsort(np.abs(f - fr))[:5]
        assert set(nearest5) <= set(idx)
    assert idx.size <= 3 * 5 + 3


def test_coherence_threshold_drops_points(frf):
    f, H, fn = frf
    idx = select_frequencies(f, H)
    coh = np.ones_like(H, dtype=float)
    bad = np.abs(f - fn[1]) < 0.01
    coh[2, bad] = 0.3  # one channel poor near the second mode
    kept = select_frequencies(f, H, coherence=coh, min_coherence=0.8)
    assert set(kept) == set(idx) - set(np.flatnonzero(bad))
    assert len(kept) < len(idx)
    with pytest.raises(InputError, match="coherence"):
        select_frequencies(f, H, min_coherence=0.8)


def test_bands_override(frf):
    f, H, _ = frf
    idx = select_frequencies(f, H, bands=[(1.0, 1.1), (7.0, 7.01)], k=0.1)
    expected = np.flatnonzero(((f >= 1.0) & (f <= 1.1)) | ((f >= 7.0) & (f <= 7.01)))
    np.testing.assert_array_equal(idx, expected)
    with pytest.raises(InputError, match=r"bands\[0\]"):
        select_frequencies(f, H, bands=[(2.0, 1.0)])


def test_plot_selection_writes_png(frf, tmp_path):
    f, H, _ = frf
    idx = select_frequencies(f, H)
    out = plot_selection(f, H, idx, tmp_path / "sel.png", channel_names=["1", "2", "3"])
    assert (tmp_path / "sel.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out == tmp_path / "sel.png"


def _shear_frame_receptance(m, k, zeta, f, floor):
    """Receptances of all floors of a shear frame to a force at `floor`, Rayleigh damping
    zeta at the first and last modes; also the undamped natural frequencies [Hz]."""
    M = np.diag(m)
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    w = np.sqrt(linalg.eigh(K, M, eigvals_only=True))
    beta = 2 * zeta / (w[0] + w[-1])
    C = w[0] * w[-1] * beta * M + beta * K
    b = np.eye(len(m))[floor]
    H = np.array([np.linalg.solve(K - wi**2 * M + 1j * wi * C, b) for wi in 2 * np.pi * f]).T
    return H, w / (2 * np.pi)


def _noisy(H, sd, seed):
    """H times exp(sd (a + j b)), a, b standard normal: ln|H| and the phase scatter by sd."""
    rng = np.random.default_rng(seed)
    return H * np.exp(sd * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))


def _peaks_6db_near(mag, f, f0):
    """Whether mag has a >= 6 dB prominent local maximum within 2 % of f0."""
    idx, _ = signal.find_peaks(20 * np.log10(mag), prominence=6.0)
    return bool(np.any(np.abs(f[idx] - f0) <= 0.02 * f0))


def test_mode_of_one_channel_kept_by_its_phase_lag():
    # heavy middle floor: mode 2 moves mostly the top floor; force at floor 1
    f = np.arange(0.5, 15, 0.02)
    H, fn = _shear_frame_receptance(np.array([0.7, 3.0, 0.6]), np.array([3000.0, 1000.0, 2250.0]),
                                    0.015, f, floor=0)
    # as built: mode 2 is a clear peak of the top floor only, not of the others nor the sum
    curves = np.vstack([np.abs(H), np.abs(H).sum(axis=0)])
    assert [_peaks_6db_near(c, f, fn[1]) for c in curves] == [False, False, True, False]
    Hn, sd = _noisy(H, 0.005, seed=3), np.full(H.shape, 0.005)
    # one channel is no majority, but its phase lags through the peak: a pole
    found = f[find_peaks(f, Hn, sigma=sd)]
    assert found.size == 3
    np.testing.assert_array_less(np.abs(found - fn) / fn, 0.02)
    # magnitudes alone cannot tell it from a bump between two zeros: majority rule only
    found = f[find_peaks(f, np.abs(Hn), sigma=sd)]
    assert found.size == 2
    np.testing.assert_array_less(np.abs(found - fn[[0, 2]]) / fn[[0, 2]], 0.02)


def test_bump_between_two_zeros_is_no_peak():
    # all channels share a mode at 11 Hz; channel 1 also has lightly damped zeros at
    # 4 and 6 Hz, so its magnitude has a local maximum near 5 Hz without a pole there
    f = np.arange(0.5, 15, 0.02)
    w = 2 * np.pi * f

    def factor(fz, zeta):
        wz = 2 * np.pi * fz
        return (wz**2 - w**2 + 2j * zeta * wz * w) / wz**2

    pole = 1 / factor(11.0, 0.02)
    zeros = factor(4.0, 0.01) * factor(6.0, 0.01)
    sd = np.full((3, f.size), 0.005)
    H = _noisy(np.vstack([zeros * pole, 2 * pole, 0.5 * pole]), 0.005, seed=4)
    found = f[find_peaks(f, H, sigma=sd)]
    assert found.size == 1 and abs(found[0] - 11.0) <= 0.02 * 11.0
    # the bump is a candidate: as a majority of channels it is reported (phase or not)
    H = _noisy(np.vstack([zeros * pole, 2 * zeros * pole, 0.5 * pole]), 0.005, seed=4)
    found = f[find_peaks(f, H, sigma=sd)]
    assert found.size == 2 and abs(found[0] - 5.0) <= 0.1 * 5.0


def test_selectable_keeps_the_band_and_the_structure_channels_coherence():
    """The points a diagnosis may add to its fit (hot-spot windows) obey the case's
    fmin, fmax and min_coherence as the half-power selection does; a base sensor's
    coherence does not rule a point out (its peaks are not looked for either)."""
    from types import SimpleNamespace
    from nlp.case.selection import selectable
    from nlp.frf.reference import BASE_DOF
    f = np.linspace(0.0, 20.0, 201)                  # 0.1 Hz steps
    coh = np.full((3, f.size), 0.9)
    coh[1, 120:131] = 0.3                            # a dip on a floor channel: 12-13 Hz
    coh[0, 50:61] = 0.1                              # the base sensor's: 5-6 Hz
    channels = [SimpleNamespace(dof=BASE_DOF), SimpleNamespace(dof=0), SimpleNamespace(dof=1)]
    fc = SimpleNamespace(fmin=1.0, fmax=14.0, min_coherence=0.5)
    ok = selectable(SimpleNamespace(frequencies=fc), f, channels, coh)
    assert ok[10] and ok[140] and not ok[9] and not ok[141]      # 1.0 and 14.0 Hz inclusive
    assert not ok[120:131].any() and ok[119] and ok[131]
    assert ok[50:61].all()
    assert ok.sum() == (140 - 10 + 1) - 11
    # no coherence rule, or no coherence: the band alone
    fc.min_coherence = None
    assert selectable(SimpleNamespace(frequencies=fc), f, channels, coh).sum() == 131
    fc.min_coherence = 0.5
    assert selectable(SimpleNamespace(frequencies=fc), f, channels, None).sum() == 131
