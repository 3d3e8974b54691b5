"""The lab's detectability rule (nlp/testing/lab/detectable.py) against finite differences
and closed forms."""

import numpy as np
import pytest

from nlp.testing.lab.detectable import (channel_frfs, log_jacobian, noise_sd, nuisance_derivatives,
                                        standard_error)


def _frame(n=3, seed=0):
    rng = np.random.default_rng(seed)
    m, k = rng.uniform(3, 6, n), rng.uniform(2000, 5000, n)
    M, K = np.diag(m), np.zeros((n, n))
    for s in range(n):
        K[s, s] += k[s]
        if s:
            K[s - 1, s - 1] += k[s]
            K[s, s - 1] -= k[s]
            K[s - 1, s] -= k[s]
    C = 1e-3 * K + 0.2 * M
    Kh = 0.01 * K
    return {"M": M, "C": C, "K": K, "m": m, "k": k}, (M, C, K, Kh)


@pytest.mark.parametrize("ground", [True, False])
def test_log_jacobian_matches_finite_differences(ground):
    st, mats = _frame()
    n = 3
    rows = np.vstack([np.eye(n), np.eye(n)[[2]]])
    kinds = ["acc", "acc", "acc", "lvdt"]
    w = 2 * np.pi * np.array([1.3, 4.0, 7.7, 12.0])
    r = np.ones(n)
    dmats = nuisance_derivatives(st, n, None)
    dmats.append(tuple(0.01 * np.asarray(m) for m in mats))          # a global scale
    J = log_jacobian(mats, dmats, w, rows, kinds, ground, 1, r)
    h = 1e-6
    for j, d in enumerate(dmats):
        up = tuple(a + h * b for a, b in zip(mats, d))
        dn = tuple(a - h * b for a, b in zip(mats, d))
        fd = (np.log(channel_frfs(up, w, rows, kinds, ground, 1, r))
              - np.log(channel_frfs(dn, w, rows, kinds, ground, 1, r))) / (2 * h)
        assert np.allclose(J[:, :, j], fd, rtol=1e-5, atol=1e-8), j


def test_standard_error_of_a_gain_is_the_weighted_mean_error():
    # ln H shifted by a gain g on one channel: d lnH/dg = 1 on its bins; a nuisance that
    # moves only the phase (imaginary part) is orthogonal to it
    sd = np.array([[0.02, 0.05, 0.1, np.nan]])
    J = np.zeros((1, 4, 2), complex)
    J[0, :, 0], J[0, :, 1] = 1.0, 1j
    want = 1 / np.sqrt(np.sum(1 / sd[0, :3] ** 2))
    assert standard_error(J, sd) == pytest.approx(want, rel=1e-12)
    # a nuisance that is the same direction leaves the parameter undetermined
    J[0, :, 1] = 1.0
    assert standard_error(J, sd) > 1e3 * want
    # ... unless a prior bounds it: SE^2 = 1 / (1/s_prior^2 ...) of the pair's difference
    s = standard_error(J, sd, prior=[np.inf, 0.01])
    assert s == pytest.approx(np.sqrt(want ** 2 + 0.01 ** 2), rel=1e-9)


def test_noise_sd_follows_the_coherence_of_a_known_snr():
    # y = x + independent noise of equal power: coherence 1/2 at every bin, so the SD of ln|H|
    # is sqrt((1 - 1/2) / (2 n_d / 2)) = 1 / sqrt(2 n_d)
    rng = np.random.default_rng(3)
    x = rng.standard_normal(2 ** 16)
    y = x + rng.standard_normal(x.size)
    f = np.linspace(5, 40, 50)
    sd, coh = noise_sd(x, [y], 100.0, 1024, f)
    assert np.median(coh) == pytest.approx(0.5, abs=0.05)
    n_d = ((x.size - 1024) // 512 + 1) / 1.056
    assert np.median(sd) == pytest.approx(1 / np.sqrt(2 * n_d), rel=0.15)
