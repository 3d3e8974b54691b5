"""FRF estimators on a random-excited 3-DOF system simulated with scipy.signal.lsim."""

import numpy as np
import pytest
from scipy import signal

from nlp.errors import InputError
from nlp.frf.estimate import estimate_frf

FS = 50.0  # Hz
N = 2**16
NPERSEG = 4096


def _matrices():
    m = np.array([2.0, 1.5, 1.0])
    k = np.array([1000.0, 750.0, 500.0])
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    C = np.array([[4.0, -0.7, 0.0], [-0.7, 2.0, -0.7], [0.0, -0.7, 1.3]])  # not Rayleigh
    return M, C, K


def _exact_frf(f, dt):
    """Receptance to a force at DOF 0, (K - w^2 M + j w C)^-1 e_0, as seen by samples.

    lsim holds the input linear between samples; that triangle kernel
    multiplies the continuous FRF by sinc^2(f dt) (aliased terms are
    negligible below 10 Hz here).
    """
    M, C, K = _matrices()
    w = 2 * np.pi * f
    H = np.array([np.linalg.solve(K - wi**2 * M + 1j * wi * C, [1.0, 0, 0]) for wi in w]).T
    return H * np.sinc(f * dt) ** 2


def _modes():
    M, C, K = _matrices()
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ K, -Mi @ C]])
    s = np.linalg.eigvals(A)
    s = s[s.imag > 0]
    return np.abs(s) / (2 * np.pi), -s.real / np.abs(s)


@pytest.fixture(scope="module")
def records():
    """White-noise force at DOF 0 and the three displacements."""
    M, C, K = _matrices()
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-Mi @ K, -Mi @ C]])
    B = np.concatenate([np.zeros(3), Mi[:, 0]])[:, None]
    Cout = np.hstack([np.eye(3), np.zeros((3, 3))])
    t = np.arange(N) / FS
    x = np.random.default_rng(0).normal(size=N)
    _, y, _ = signal.lsim((A, B, Cout, np.zeros((3, 1))), x, t)
    return x, y.T


@pytest.mark.parametrize("estimator", ["H1", "H2", "Hv"])
def test_magnitude_and_phase_near_resonances(records, estimator):
    x, y = records
    est = estimate_frf(x, y, FS, estimator=estimator, nperseg=NPERSEG)
    assert est.H.shape == (3, NPERSEG // 2 + 1) and est.estimator == estimator
    assert est.f[1] == pytest.approx(FS / NPERSEG)
    H = _exact_frf(est.f, 1 / FS)
    for fn, zeta in zip(*_modes()):
        band = np.abs(est.f - fn) <= 2 * zeta * fn  # about the half-power band
        assert band.sum() >= 10
        ratio = est.H[:, band] / H[:, band]
        assert np.max(np.abs(np.abs(ratio) - 1)) < 0.08
        # a conjugated FRF would be off by ~pi here
        assert np.max(np.abs(np.angle(ratio))) < 0.08
        assert np.min(est.coherence[:, band]) > 0.95


def test_receptance_has_negative_imaginary_part_at_point_resonance(records):
    x, y = records
    est = estimate_frf(x, y, FS, nperseg=NPERSEG)
    for fn, _ in zip(*_modes()):
        assert est.H[0, np.argmin(np.abs(est.f - fn))].imag < 0


def test_coherence_falls_as_output_noise_rises(records):
    x, y = records
    rng = np.random.default_rng(1)
    means = []
    for level in (0.0, 0.3, 1.0, 3.0):
        noisy = y + level * y.std(axis=1, keepdims=True) * rng.normal(size=y.shape)
        est = estimate_frf(x, noisy, FS, nperseg=1024)
        band = (est.f > 0.5) & (est.f < 10.0)
        means.append(est.coherence[:, band].mean())
        h1 = estimate_frf(x, noisy, FS, "H1", nperseg=1024).H[:, band]
        h2 = estimate_frf(x, noisy, FS, "H2", nperseg=1024).H[:, band]
        hv = estimate_frf(x, noisy, FS, "Hv", nperseg=1024).H[:, band]
        # |H2| / |H1| = 1 / coherence >= 1, Hv in between
        assert np.all(np.abs(h2) >= np.abs(h1) * (1 - 1e-12))
        assert np.all(np.abs(hv) >= np.abs(h1) * (1 - 1e-12))
        assert np.all(np.abs(hv) <= np.abs(h2) * (1 + 1e-12))
    assert means[0] > 0.9
    assert all(a > b + 0.05 for a, b in zip(means, means[1:]))


def test_input_noise_biases_h1_low_but_not_h2(records):
    # white input noise of the input's variance: E[H1] = H / (1 + 1) = H / 2, H2 = H
    x, y = records
    xn = x + np.random.default_rng(2).normal(size=x.size)
    f = estimate_frf(xn, y, FS, "H1", nperseg=1024).f
    band = (f > 0.5) & (f < 10.0)
    H = _exact_frf(f[band], 1 / FS)
    h1 = estimate_frf(xn, y, FS, "H1", nperseg=1024).H[:, band]
    h2 = estimate_frf(xn, y, FS, "H2", nperseg=1024).H[:, band]
    assert np.median(np.abs(h1 / H)) == pytest.approx(0.5, rel=0.05)
    assert np.median(np.abs(h2 / H)) == pytest.approx(1.0, rel=0.05)


def test_single_channel_1d_output():
    x = np.random.default_rng(3).normal(size=512)
    est = estimate_frf(x, 2.0 * x, 100.0, nperseg=64)
    np.testing.assert_allclose(est.H[0, 1:], 2.0, rtol=1e-10)  # y = 2 x exactly
    np.testing.assert_allclose(est.coherence[0, 1:], 1.0, rtol=1e-10)


@pytest.mark.parametrize("kwargs, key", [
    (dict(y=np.zeros((2, 99))), "'y'"),
    (dict(x=np.r_[np.zeros(50), np.nan, np.zeros(49)]), "'x'"),
    (dict(y=np.r_[np.zeros(99), np.inf][None, :]), r"'y\[0\]'"),
    (dict(nperseg=101), "'nperseg'"),
    (dict(estimator="H3"), "'estimator'"),
    (dict(fs=-1.0), "'fs'"),
])
def test_bad_input(kwargs, key):
    args = dict(x=np.ones(100), y=np.ones((2, 100)), fs=10.0, nperseg=32)
    args.update(kwargs)
    with pytest.raises(InputError, match=key) as info:
        estimate_frf(**args)
    assert info.value.file == "<data>"


def _tls_by_definition(s_xx, s_yy, s_xy):
    """Hv at each frequency: -v_x / v_y of the eigenvector of the smallest
    eigenvalue of [[S_xx, S_xy], [S_yx, S_yy]] (numpy's eigh, not the closed form)."""
    out = np.empty(s_xy.shape, complex)
    for i in range(s_xy.size):
        G = np.array([[s_xx[i], s_xy[i]], [np.conj(s_xy[i]), s_yy[i]]])
        _, V = np.linalg.eigh(G)
        out[i] = -V[0, 0] / V[1, 0]
    return out


def test_hv_is_the_total_least_squares_solution_with_noise_on_input_and_output():
    """FIR system y = 0.8 x[n] + 0.5 x[n-1], white noise of equal variance on x and y:
    H1 is biased low by S_xx / (S_xx + S_nn), H2 high; Hv equals the TLS eigenvector
    solution and is unbiased for equal noise."""
    rng = np.random.default_rng(7)
    n, fs, nper = 2**17, 100.0, 256
    u = rng.normal(size=n)
    v = 0.8 * u + 0.5 * np.concatenate([[0.0], u[:-1]])
    x = u + 0.5 * rng.normal(size=n)
    y = v + 0.5 * rng.normal(size=n)
    est = estimate_frf(x, y, fs, estimator="Hv", nperseg=nper)
    kw = dict(fs=fs, nperseg=nper)
    _, s_xx = signal.welch(x, **kw)
    _, s_yy = signal.welch(y, **kw)
    _, s_xy = signal.csd(x, y, **kw)
    np.testing.assert_allclose(est.H[0], _tls_by_definition(s_xx, s_yy, s_xy), rtol=1e-10)
    w = 2 * np.pi * est.f / fs
    true = 0.8 + 0.5 * np.exp(-1j * w)
    h1 = estimate_frf(x, y, fs, estimator="H1", nperseg=nper).H[0]
    inner = slice(5, -5)
    assert np.median(np.abs(est.H[0, inner] / true[inner] - 1)) < 0.03
    assert np.median(np.abs(h1[inner]) / np.abs(true[inner])) == pytest.approx(0.8, abs=0.03)
    assert est.n_averages == (n - nper) // (nper // 2) + 1


def test_records_average_all_segments_like_one_long_record(records):
    """With no overlap, splitting a record at a segment boundary into two records
    must give the same averaged spectra, hence the same FRF, coherence and count."""
    x, y = records
    nper = 1024
    one = estimate_frf(x[:8 * nper], y[:, :8 * nper], FS, nperseg=nper, noverlap=0)
    two = estimate_frf([x[:3 * nper], x[3 * nper:8 * nper]],
                       [y[:, :3 * nper], y[:, 3 * nper:8 * nper]], FS, nperseg=nper, noverlap=0)
    assert one.n_averages == two.n_averages == 8
    np.testing.assert_allclose(two.H, one.H, rtol=1e-10)
    np.testing.assert_allclose(two.coherence, one.coherence, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("nperseg,noverlap", [(1024, None), (1024, 768), (1000, 0)])
def test_averaging_count_is_the_number_of_welch_segments(records, nperseg, noverlap):
    """n_averages equals the segments scipy.signal.spectrogram cuts with the same settings."""
    x, y = records
    est = estimate_frf(x, y, FS, nperseg=nperseg, noverlap=noverlap)
    # spectrogram's default overlap differs from Welch's (half): give it explicitly
    _, t, _ = signal.spectrogram(x, FS, nperseg=nperseg,
                                 noverlap=nperseg // 2 if noverlap is None else noverlap)
    assert est.n_averages == t.size
