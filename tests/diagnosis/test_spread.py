"""The sampling spread of a reduced chi-square with correlated errors (nlp.diagnosis.spread),
against closed forms and against the spread of many simulated draws."""

import numpy as np
import pytest

from nlp.diagnosis.spread import chi2_spread, effective_points


def _shared(rng, rho, nc, nf):
    """Unit-variance errors with correlation rho between every two channels at a bin."""
    c = rng.standard_normal(nf)
    return np.sqrt(rho) * c + np.sqrt(1 - rho) * rng.standard_normal((nc, nf))


def _ar1(rng, phi, nc, windows, width):
    """Unit-variance AR(1) errors along each window of `width` consecutive bins."""
    out = np.empty((nc, windows * width))
    for w in range(windows):
        x = rng.standard_normal(nc)
        for j in range(width):
            out[:, w * width + j] = x
            x = phi * x + np.sqrt(1 - phi ** 2) * rng.standard_normal(nc)
    return out


def test_independent_errors_count_every_point():
    rng = np.random.default_rng(0)
    n = effective_points(rng.standard_normal((3, 400)))
    assert 0.85 * 1200 <= n <= 1200


def test_errors_shared_between_channels_match_the_closed_form():
    # N_eff = N^2 / (nf (nc + nc (nc - 1) rho^2)) for equicorrelated channels
    rng = np.random.default_rng(1)
    nc, nf, rho = 3, 300, 0.6
    theory = (nc * nf) ** 2 / (nf * (nc + nc * (nc - 1) * rho ** 2))
    est = np.mean([effective_points(_shared(rng, rho, nc, nf)) for _ in range(20)])
    assert est == pytest.approx(theory, rel=0.1)
    # one common error on every channel: one independent point per bin
    c = rng.standard_normal(nf)
    assert effective_points(np.vstack([c, c, c])) == pytest.approx(nf, rel=0.05)


@pytest.mark.parametrize("kind", ["shared", "ar1"])
def test_predicted_spread_matches_simulated_draws(kind):
    rng = np.random.default_rng(2)
    if kind == "shared":
        draw, idx = (lambda: _shared(rng, 0.5, 3, 150)), None
    else:   # 8 windows of 20 bins, far apart on the grid, correlated along each
        draw = lambda: _ar1(rng, 0.5, 3, 8, 20)                               # noqa: E731
        idx = np.concatenate([np.arange(100 * k, 100 * k + 20) for k in range(8)])
    observed = np.std([np.mean(draw() ** 2) for _ in range(3000)])
    predicted = np.mean([chi2_spread(draw(), idx)[0] for _ in range(30)])
    assert predicted == pytest.approx(observed, rel=0.12)
    # counting the points as independent would understate it
    assert np.sqrt(2 / draw().size) < 0.85 * observed


def test_bins_far_apart_on_the_grid_are_not_paired():
    # the same AR(1) columns, but each bin its own window: no lag correlation is counted
    rng = np.random.default_rng(3)
    z = _ar1(rng, 0.9, 2, 1, 400)
    near = effective_points(z, np.arange(400))
    apart = effective_points(z, 10 * np.arange(400))
    assert near < 0.5 * apart
