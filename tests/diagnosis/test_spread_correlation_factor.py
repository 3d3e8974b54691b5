"""The correlation factor of a chi-square drop (nlp.diagnosis.spread.correlation_factor)
against closed forms for moving-average errors and against simulated regressions."""

import numpy as np
import pytest

from nlp.diagnosis.spread import correlation_factor

B = np.array([1.0, 0.6, 0.3])          # MA(2): x_i = e_i + 0.6 e_(i-1) + 0.3 e_(i-2)
RHO1 = (B[0] * B[1] + B[1] * B[2]) / np.sum(B ** 2)
RHO2 = B[0] * B[2] / np.sum(B ** 2)


def _ma(rng, n):
    return np.convolve(rng.standard_normal(n + 2), B, mode="valid")


def test_white_residuals_give_one_and_ma_residuals_their_long_run_sum():
    rng = np.random.default_rng(1)
    n = 20000
    smooth = np.sin(2 * np.pi * np.arange(n) / 4000.0)[:, None]
    assert correlation_factor(rng.standard_normal(n), smooth, np.arange(n)) == pytest.approx(1, abs=0.05)
    # a column smooth along frequency sees sum_l rho_l; one alternating in sign sees
    # 1 - 2 rho_1 + 2 rho_2 (a^T R a / a^T a for the two columns)
    x = _ma(rng, n)
    assert correlation_factor(x, smooth, np.arange(n)) == pytest.approx(1 + 2 * (RHO1 + RHO2), rel=0.05)
    alt = np.where(np.arange(n) % 2, 1.0, -1.0)[:, None]
    assert correlation_factor(x, alt, np.arange(n)) == pytest.approx(1 - 2 * RHO1 + 2 * RHO2, rel=0.1)


def test_two_channels_with_a_shared_error_frequency_major():
    # r_i = (e_i + c, e'_i + c) per frequency, a column moving both channels alike:
    # a^T Sigma a / (a^T a phi) = (1 + rho_x) with rho_x = s_c^2 / (1 + s_c^2)
    rng = np.random.default_rng(2)
    n, sc = 20000, 0.8
    common = sc * rng.standard_normal(n)
    U = rng.standard_normal((n, 2)) + common[:, None]
    a = np.ones((n, 2)) * np.cos(2 * np.pi * np.arange(n) / 5000.0)[:, None]
    f = correlation_factor(U.ravel(), a.reshape(-1, 1), np.arange(n))
    assert f == pytest.approx(1 + sc ** 2 / (1 + sc ** 2), rel=0.05)


def test_the_factor_predicts_the_simulated_drop():
    # least squares of a null regressor on MA(2) errors: the mean drop over phi is the
    # factor, where an independent-error reading expects 1
    rng = np.random.default_rng(3)
    n, draws = 2000, 400
    a = np.sin(2 * np.pi * np.arange(n) / 400.0)
    drops, factors = [], []
    for _ in range(draws):
        x = _ma(rng, n)
        drops.append((a @ x) ** 2 / (a @ a) / np.mean(x ** 2))
        factors.append(correlation_factor(x, a[:, None], np.arange(n)))
    se = np.std(drops) / np.sqrt(draws)
    assert abs(np.mean(drops) - np.mean(factors)) < 4 * se
    assert np.mean(drops) > 2.0          # the uncorrected reading is off by over 2x


def test_a_factor_that_cannot_be_formed_is_one():
    rng = np.random.default_rng(4)
    x = _ma(rng, 400)
    assert correlation_factor(x[:4], np.ones((4, 1)), np.arange(4)) == 1.0     # too few bins
    assert correlation_factor(x, np.zeros((400, 1)), np.arange(400)) == 1.0    # no column
    assert correlation_factor(np.zeros(400), np.ones((400, 1)), np.arange(400)) == 1.0
