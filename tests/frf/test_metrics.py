"""Metrics against hand computations."""

import numpy as np
import pytest

from nlp.errors import InputError
from nlp.frf.metrics import (correlation, fdac, fdac_overall, frac, mac, modal_errors, nrmse,
                         peak_error)


def _sdof(f, fn=5.0, zeta=0.02):
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    return 1.0 / (wn**2 - w**2 + 2j * zeta * wn * w)


def test_identical_and_scaled_frfs_give_one():
    f = np.linspace(1, 10, 50)
    H = np.vstack([_sdof(f), _sdof(f, 7.0)])
    np.testing.assert_allclose(fdac(H, H), [1.0, 1.0])
    np.testing.assert_allclose(frac(H, H), [1.0, 1.0])
    # FDAC is blind to scale and phase: 3 e^{j0.7} H still gives 1
    np.testing.assert_allclose(fdac(3.0 * np.exp(0.7j) * H, H), [1.0, 1.0])
    assert fdac_overall(H, H) == pytest.approx(1.0)


def test_hand_worked_two_point_examples():
    # |H_a| = [1, 2], |H_x| = [2, 1]: (1*2 + 2*1)^2 / (5 * 5) = 16/25
    assert fdac([1.0, 2.0j], [-2.0, 1.0])[0] == pytest.approx(0.64)
    # FRAC, H_a = [1, j], H_x = [1, 1]: |1 + j|^2 / (2 * 2) = 0.5
    assert frac([1.0, 1j], [1.0, 1.0])[0] == pytest.approx(0.5)
    # FDAC of the same pair ignores the phase: (1 + 1)^2 / (2 * 2) = 1
    assert fdac([1.0, 1j], [1.0, 1.0])[0] == pytest.approx(1.0)
    # overall concatenates channels: a = [1, 2, 1, 0], x = [2, 1, 1, 0] -> 25 / (6 * 6)
    assert fdac_overall([[1, 2], [1, 0]], [[2, 1], [1, 0]]) == pytest.approx(25 / 36)


def test_orthogonal_gives_zero():
    assert fdac([1.0, 0.0], [0.0, 1.0])[0] == 0.0
    assert frac([1.0, 1.0], [1.0, -1.0])[0] == 0.0
    np.testing.assert_allclose(mac(np.eye(3), np.eye(3)), np.eye(3))


def test_mac_complex_scaling_and_hand_value():
    rng = np.random.default_rng(0)
    phi = rng.normal(size=(4, 2)) + 1j * rng.normal(size=(4, 2))
    m = mac(phi, phi * np.array([2 - 1j, -0.5j]))
    np.testing.assert_allclose(np.diag(m), [1.0, 1.0])
    # [1, 1] vs [1, 0]: 1 / (2 * 1)
    assert mac(np.array([1.0, 1.0]), np.array([1.0, 0.0]))[0, 0] == pytest.approx(0.5)
    assert mac(phi, phi[:, :1]).shape == (2, 1)


def test_time_domain_metrics():
    meas = np.array([1.0, -1.0, 1.0, -1.0])
    sim = np.array([1.5, -0.5, 1.5, -0.5])
    assert nrmse(sim, meas) == pytest.approx(0.5)  # rms(0.5) / rms(1)
    assert peak_error(np.array([0, 3.0, -1]), np.array([1.0, -2.0, 0])) == pytest.approx(0.5)
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(2, 200))
    assert correlation(a, 0.3 * a + b) == pytest.approx(np.corrcoef(a, 0.3 * a + b)[0, 1])
    assert correlation(a, -2 * a + 1) == pytest.approx(-1.0)
    np.testing.assert_allclose(nrmse(np.vstack([sim, meas]), np.vstack([meas, meas])), [0.5, 0])


def test_modal_errors_pairs_by_nearest_frequency():
    f_x = np.array([10.0, 2.0, 5.0])
    z_x = np.array([0.02, 0.01, 0.03])
    f_a = np.array([2.2, 5.0, 9.0, 30.0])
    z_a = np.array([0.015, 0.03, 0.05, 0.1])
    df, dz, pair = modal_errors(f_a, z_a, f_x, z_x)
    np.testing.assert_array_equal(pair, [2, 0, 1])
    np.testing.assert_allclose(df, [-0.1, 0.1, 0.0])
    np.testing.assert_allclose(dz, [0.03, 0.005, 0.0])
    # fewer analytical modes than measured: the far one is left unpaired
    df, dz, pair = modal_errors([2.0], [0.01], [2.1, 8.0], [0.01, 0.02])
    assert pair.tolist() == [0, -1] and np.isnan(df[1]) and np.isnan(dz[1])


def test_shape_mismatch_is_input_error():
    with pytest.raises(InputError):
        fdac(np.ones((2, 3)), np.ones((3, 3)))
    with pytest.raises(InputError):
        nrmse(np.ones(3), np.ones(4))
