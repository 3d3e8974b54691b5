"""Flags of a fit as a whole: a best objective one start reached, a misfit far above the noise."""

import numpy as np

from nlp.output.flags import MISFIT_RATIO, misfit_flag, single_start_flag


def test_single_start_flag_only_when_one_of_several_reached_the_best():
    assert single_start_flag(1, 4, 0.01)["kind"] == "single_start"
    assert single_start_flag(2, 4, 0.01) is None
    assert single_start_flag(1, 1, 0.01) is None   # one start: nothing to compare


def test_misfit_flag_at_the_ratio():
    rng = np.random.default_rng(0)
    sigma = 0.01
    e = rng.normal(0, sigma, 4000)                  # a fit at the noise floor
    rms = float(np.sqrt(np.mean(e ** 2)))
    assert misfit_flag(rms, sigma, e.size) is None
    fl = misfit_flag((MISFIT_RATIO + 0.1) * sigma, sigma, e.size)
    assert fl["kind"] == "misfit_above_noise" and np.isclose(fl["ratio"], MISFIT_RATIO + 0.1)
    assert misfit_flag(np.nan, sigma, 10) is None and misfit_flag(1.0, 0.0, 10) is None


def test_undetermined_flag_counts_the_directions_the_data_leave_open():
    """A linear least-squares fit of relative parameters with known singular values: the
    standard error along right singular vector k is s / sigma_k (the covariance is
    s^2 (J^T J)^-1), so exactly the directions with sigma_k < s are undetermined."""
    from nlp.output.flags import undetermined_flag
    from nlp.solve.identify import standard_errors
    rng = np.random.default_rng(3)
    m, n, s = 400, 6, 0.05
    U, _ = np.linalg.qr(rng.standard_normal((m, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    sv = np.array([5.0, 2.0, 1.0, 0.3, 0.04, 0.01])        # s / sv > 1 for the last two
    J = U @ np.diag(sv) @ V.T
    r = rng.standard_normal(m)
    r *= s * np.sqrt(m - n) / np.linalg.norm(r)            # s^2 = r^T r / (m - n)
    cov, s2, _ = standard_errors(J, r, m)
    assert np.isclose(s2, s ** 2)
    names = [f"k{i + 1}" for i in range(n)]
    fl = undetermined_flag(cov, names, np.zeros(n))
    assert fl["kind"] == "undetermined"
    assert fl["combinations"] == int(np.sum(s / sv > 1.0)) == 2
    se = np.sqrt(np.diag(cov))
    assert fl["parameters_above_100_percent"] == [nm for nm, x in zip(names, se) if x > 1]
    # the same data with every direction determined: no flag
    J2 = U @ np.diag(np.maximum(sv, 0.2)) @ V.T
    assert undetermined_flag(standard_errors(J2, r, m)[0], names, np.zeros(n)) is None
    # a relative standard error is that of the value nominal x (1 + theta)
    one = undetermined_flag(np.diag([1.21, 0.01]), ["a", "b"], np.array([0.5, 0.0]))
    assert one["combinations"] == 1 and one["parameters_above_100_percent"] == []
