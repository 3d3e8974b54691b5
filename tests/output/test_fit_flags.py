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
