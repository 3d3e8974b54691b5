"""Noise model per FRF route: null cases (physics inside the model class) fit to
a reduced chi-square near 1 on every route.

Records and FRFs are simulated here by nlp/testing/noise_sim.py (scipy lsim of a
3-storey frame at 10x the recorded rate, noise on the input and every output),
independently of the package's FRF and time-stepping code; the package only
estimates, weighs and fits.
"""

import math

import numpy as np
import pytest

from nlp.testing import noise_sim as sf
from nlp.frf import kernel, noise, scatter, variance
from nlp.case.assemble import assemble
from nlp.case.load import load_case


@pytest.mark.parametrize("route", sf.ROUTES)
def test_null_case_has_reduced_chi2_near_one(tmp_path, route):
    """One null case per FRF route: one-segment chirp, Welch, FRF file without and
    with coherence (simulated per bin, and an analyzer's Welch average); the package's
    noise model makes the fit a chi-square."""
    chi2, model, case = sf.reduced_chi2(sf.null_case(route, tmp_path, seed=1))
    assert model.route == {"frf_scatter": "scatter", "frf_welch": "frf_coherence",
                           "frf_welch_bare": "scatter"}.get(route, route)
    # an analyzer's Hann average, with or without its coherence: the model carries the
    # window's kernel
    assert (case.target.kernel is not None) == (route in ("welch", "frf_welch", "frf_welch_bare"))
    assert 0.8 <= chi2 <= 1.3, chi2
    # what the user is told the level is worth: a level read from the FRF's own scatter
    # says its range, and this null case lies inside it
    told = noise.describe(model)
    assert told["route"] == model.route and told["measured"] == (route != "frf_scatter" and
                                                                   route != "frf_welch_bare")
    if not told["measured"]:
        assert noise.SCATTER_RANGE[0] <= chi2 <= noise.SCATTER_RANGE[1]
    inside = (case.f > 1) & (case.f < 9)
    s = model.sigma_ln[:, inside]
    if route == "transient":     # the scatter of ln|H| follows the response (peaks vs shoulders)
        assert s.max() / s.min() > 10
    if route == "welch":         # 4096-sample segments of 30000 samples, half overlap
        assert 12 < model.n_averages < 14
    if route == "frf_scatter":   # follows the 1 % -> 4 % ramp of the simulated noise
        lo, hi = model.sigma_ln[:, case.f < 2].mean(), model.sigma_ln[:, case.f > 10].mean()
        assert 2.0 < hi / lo < 5.0
    if route == "frf_coherence":
        assert model.n_averages == 30


def test_transient_variance_matches_monte_carlo():
    """Var ln|Y/X| of one noisy DFT bin against the errors-in-variables formula."""
    rng = np.random.default_rng(4)
    U, Hk = 2.0 + 1.0j, 0.5 - 0.3j
    s_nx, s_ny = 0.04, 0.01                          # noise powers of the bins
    n = 200000
    nx = math.sqrt(s_nx / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    ny = math.sqrt(s_ny / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    est = np.log((Hk * U + ny) / (U + nx))
    p_xx = np.array([abs(U) ** 2 + s_nx])
    p_yy = np.array([[abs(Hk * U) ** 2 + s_ny]])
    var = variance.var_ln_transient(p_xx, p_yy, np.array([s_nx]), np.array([[s_ny]]))[0, 0]
    assert np.var(est.real) == pytest.approx(var, rel=0.05)
    assert np.var(est.imag) == pytest.approx(var, rel=0.05)


def test_welch_overlap_correction():
    """Hann at 50 % overlap: rho_1 = 1/6, so n_eff = n_d / (1 + 2 (1 - 1/n_d) / 36)."""
    n_d, n_eff = kernel.welch_averages(1024 * 10, 1024, 512, "hann")
    assert n_d == 19
    assert n_eff == pytest.approx(19 / (1 + 2 * (1 - 1 / 19) / 36), rel=1e-3)
    assert kernel.welch_averages(4096, 1024, 0, "hann") == (4, 4.0)
    assert kernel.kernel_moment("hann", 4096) == pytest.approx(1 / 3, rel=1e-4)


def test_chirp_noise_above_last_mode_is_not_a_mode(tmp_path):
    """fmax at the top of the excitation band (20 Hz), last mode at 7.4 Hz: the
    half-power selection keeps the three modes only."""
    path = sf.null_case("transient", tmp_path, seed=6, frequencies={"fmax": 20.0})
    case = assemble(load_case(path))
    M, _, K = sf.frame()
    modes = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)) / (2 * np.pi)
    f_sel = case.f[case.selected]
    near = np.min(np.abs(f_sel[:, None] - modes[None, :]) / modes[None, :], axis=1)
    assert near.max() < 0.1, f_sel[near >= 0.1]
    assert all(np.any(np.abs(f_sel - fr) < 0.01 * fr) for fr in modes)


def test_resolution_bias_of_a_flat_noisy_estimate_is_its_noise():
    """On a flat FRF the resolution bias read from second differences is noise alone: for
    a Welch H1 (Hann, 50 % overlap) of y = x + noise its mean square is
    (m2/2)^2 x second_difference_factor x s^2, s the point scatter of ln|H1| (measured
    here directly, H = 1), which the file route takes off the squared bias."""
    from scipy import signal
    rng = np.random.default_rng(3)
    x = rng.standard_normal(400 * 1024)
    y = x + 0.3 * rng.standard_normal(x.size)
    _, sxy = signal.csd(x, y, nperseg=1024)
    _, sxx = signal.welch(x, nperseg=1024)
    H = (sxy / sxx)[None, 5:-5]
    s_true = np.std(np.log(np.abs(H)))
    m2 = kernel.kernel_moment("hann", 1024)
    b2 = np.mean(kernel.resolution_bias(H, m2)[0, 1:-1] ** 2)
    expect = (0.5 * m2) ** 2 * scatter.second_difference_factor("hann") * s_true ** 2
    assert b2 == pytest.approx(expect, rel=0.1)
    s, _ = scatter.local_scatter(np.arange(H.shape[1], dtype=float), H, window="hann")
    assert np.median(s) == pytest.approx(s_true, rel=0.1)


def _welch_file_of_a_sharp_mode(seed, zeta, fs=50.0, fn=5.0, nperseg=2048, segments=30):
    """An analyzer-style H1 (Hann, no overlap, no coherence stored) of a resonance a
    few bins wide, and its true FRF: a bilinear filter run by scipy, read by freqz."""
    from scipy import signal
    rng = np.random.default_rng(seed)
    wn = 2 * math.pi * fn
    b, a = signal.bilinear([wn ** 2], [1, 2 * zeta * wn, wn ** 2], fs)
    n = nperseg * segments
    x = rng.standard_normal(n + 4000)
    y = signal.lfilter(b, a, x)[4000:]
    x = x[4000:]
    x = x + 0.02 * np.std(x) * rng.standard_normal(n)
    y = y + 0.02 * np.std(y) * rng.standard_normal(n)
    f, sxy = signal.csd(x, y, fs=fs, nperseg=nperseg)
    _, sxx = signal.welch(x, fs=fs, nperseg=nperseg)
    keep = (f > 0.5) & (f < 20)
    _, Ht = signal.freqz(b, a, worN=f[keep], fs=fs)
    return f[keep], (sxy / sxx)[keep], Ht


@pytest.mark.parametrize("zeta", [0.01, 0.02])
def test_file_noise_covers_the_error_at_a_sharp_peak(zeta):
    """An FRF file without coherence: at the 7 bins around a peak 3-7 bins wide (half
    power), the actual error ln|H1 / H| over the scatter route's sigma has a mean
    square near 1 over 20 records (2.1 when the resolution bias was read bin by bin:
    it lands on one bin and misses its neighbour)."""
    from types import SimpleNamespace
    cfg = SimpleNamespace(data=SimpleNamespace(window="hann"))
    z2 = []
    for seed in range(20):
        f, H, Ht = _welch_file_of_a_sharp_mode(seed, zeta)
        m = noise.noise_model(SimpleNamespace(config=cfg, f=f, H=H[None], coherence=None,
                                              records=None, channels=(None,),
                                              n_averages=None, kernel=None))
        assert m.route == "scatter"
        k = int(np.argmax(np.abs(Ht)))
        z2.append((np.log(np.abs(H / Ht)) / m.sigma_ln[0])[k - 3:k + 4] ** 2)
    assert 0.6 < np.mean(z2) < 1.6, np.mean(z2)


def _file_case(window="hann", coherence=True, n_averages=13, overlap=0.5):
    """A flat FRF file (H = 1 + 0j on a uniform grid) as assemble would pass it on."""
    from types import SimpleNamespace
    f = np.arange(0.5, 10.0, 0.025)
    cfg = SimpleNamespace(data=SimpleNamespace(window=window, overlap=overlap, nperseg=None))
    coh = np.full((1, f.size), 0.9) if coherence else None
    return cfg, f, SimpleNamespace(config=cfg, f=f, H=np.ones((1, f.size), complex),
                                   coherence=coh, records=None, channels=(None,),
                                   n_averages=n_averages if coherence else None)


def test_an_averaged_file_carries_its_window_kernel():
    """A file with its coherence and averages is a windowed average: three taps with the
    Hann power kernel's moments (m2 = 1/3 bin^2 from Parseval, m4 = 1/3), so h = 1 bin
    and a = m2^2 / (2 m4) = 1/6. A file without coherence is taken as such an average
    too; one that states a single average, or window none, has no kernel."""
    cfg, f, _ = _file_case()
    h, a = kernel.estimator_kernel(cfg, f, None, np.ones((1, f.size)), 13)
    assert h == pytest.approx(2 * math.pi * 0.025, rel=1e-3)
    assert a == pytest.approx(1 / 6, rel=1e-3)
    assert kernel.estimator_kernel(cfg, f, None, None, None) == pytest.approx((h, a))
    assert kernel.estimator_kernel(cfg, f, None, np.ones((1, f.size)), 1) is None
    cfg_none, _, _ = _file_case(window="none")
    assert kernel.estimator_kernel(cfg_none, f, None, np.ones((1, f.size)), 13) is None


def test_file_coherence_variance_counts_overlapping_averages():
    """13 Hann averages at half overlap are worth 13 / (1 + 2 (1 - 1/13) / 36)
    independent ones (Welch 1967, rho_1 = 1/6): Var ln|H| = (1 - g^2) / (2 n_eff g^2).
    With the window's kernel in the model the fit's sigma holds no resolution bias."""
    cfg, f, case = _file_case()
    case.kernel = kernel.estimator_kernel(cfg, f, None, case.coherence, 13)
    m = noise.noise_model(case)
    n_eff = 13 / (1 + 2 * (1 - 1 / 13) / 36)
    assert m.route == "frf_coherence"
    assert m.n_averages == pytest.approx(n_eff, rel=1e-3)
    np.testing.assert_allclose(m.sigma_ln ** 2, (1 - 0.9) / (2 * n_eff * 0.9), rtol=1e-6)
    _, _, case0 = _file_case(overlap=0.0)
    assert noise.noise_model(case0).n_averages == pytest.approx(13, rel=1e-6)


@pytest.mark.parametrize("zeta", [0.01, 0.02])
def test_file_noise_with_the_kernel_covers_the_leakage_at_a_sharp_peak(zeta):
    """The same file with the window's kernel in the model (three taps, h = 1 bin,
    a = 1/6): the bias is the model's now, the leakage scatter at the peak is not. At
    the 7 bins around the peak, ln|H1| against the smoothed true FRF over the scatter
    route's sigma (with LEAKAGE_KEEP of the squared bias) has a mean square near 1
    over 20 records."""
    from types import SimpleNamespace
    from scipy import signal
    cfg = SimpleNamespace(data=SimpleNamespace(window="hann"))
    fs, fn, nperseg = 50.0, 5.0, 2048
    wn = 2 * math.pi * fn
    b, a = signal.bilinear([wn ** 2], [1, 2 * zeta * wn, wn ** 2], fs)
    z2 = []
    for seed in range(20):
        f, H, Ht = _welch_file_of_a_sharp_mode(seed, zeta)
        df = f[1] - f[0]
        h, w = kernel.smoothing_taps("hann", nperseg)
        Hs = sum(g * signal.freqz(b, a, worN=f + s * h * df, fs=fs)[1]
                 for g, s in ((w, -1), (1 - 2 * w, 0), (w, 1)))
        m = noise.noise_model(SimpleNamespace(config=cfg, f=f, H=H[None], coherence=None,
                                              records=None, channels=(None,),
                                              n_averages=None, kernel=(2 * math.pi * h * df, w)))
        assert m.route == "scatter"
        assert np.all(m.detect >= m.sigma_ln - 1e-12)
        k = int(np.argmax(np.abs(Ht)))
        z2.append((np.log(np.abs(H / Hs)) / m.sigma_ln[0])[k - 3:k + 4] ** 2)
    print(zeta, np.mean(z2))
    assert 0.6 < np.mean(z2) < 1.6, np.mean(z2)
