"""scripts/make_planted_joint.py: an effect planted in two tests of one frame (shaker at
floors 1 and 2) equals, in both, the frame with the effect solved directly."""

import numpy as np
import pytest

from support.paths import load_script

CASE = {"excitation": {"floor": 1}, "model": {"masses": [5.0, 4.6, 4.8]},
        "data": {"file": "a.csv", "tests": [{"file": "b.csv", "force_floor": 2}],
                 "channels": [{"name": f"floor{j + 1}", "floor": j + 1, "column": c}
                              for j, c in enumerate((2, 0, 1))]}}   # columns out of floor order
F = np.linspace(3.0, 45.0, 400)
W = 2 * np.pi * F


def _load(name):
    return load_script(name, ("make_planted_real",))


def _frame():
    m = np.array(CASE["model"]["masses"])
    k = np.array([5.2e4, 4.9e4, 4.4e4])
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    C = 1e-4 * K + 0.3 * np.diag(m)
    C[0, 2] = C[2, 0] = -2.0          # a non-proportional, non-adjacent dashpot
    C[0, 0] += 2.0
    C[2, 2] += 2.0
    return np.diag(m), K, C


def _table(M, K, C, b, n=3):
    """Accelerances of floors 1..n for a force at floor b, as a data table (f, columns)."""
    cols = [ch["column"] for ch in CASE["data"]["channels"]]
    t = np.zeros((len(F), 1 + n), complex)
    t[:, 0] = F
    for i, w in enumerate(W):
        x = np.linalg.solve(K - w**2 * M + 1j * w * C, np.eye(len(M))[b - 1])
        t[i, 1 + np.array(cols)] = -w**2 * x[:n]
    return t


def _with_appendage(M, K, C, p, m_a, f_a, zeta):
    n = len(M)
    k_a = m_a * (2 * np.pi * f_a) ** 2
    c_a = 2 * zeta * m_a * 2 * np.pi * f_a
    Ma, Ka, Ca = (np.zeros((n + 1, n + 1)) for _ in range(3))
    Ma[:n, :n], Ka[:n, :n], Ca[:n, :n] = M, K, C
    Ma[n, n] = m_a
    for A, v in ((Ka, k_a), (Ca, c_a)):
        A[np.ix_([p - 1, n], [p - 1, n])] += v * np.array([[1, -1], [-1, 1]])
    return Ma, Ka, Ca


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("p", [1, 2])
def test_appendage_in_both_tests_equals_the_direct_solve(p):
    mod = _load("make_planted_joint")
    M, K, C = _frame()
    tables = {1: _table(M, K, C, 1), 2: _table(M, K, C, 2)}
    truth = {"family": "secondary_oscillator", "location": {"floor": p},
             "size": {"m_a_kg": 0.6, "f_a_hz": 21.0, "zeta_a": 0.02}}
    planted = mod.plant(tables, CASE, truth)
    Ma, Ka, Ca = _with_appendage(M, K, C, p, 0.6, 21.0, 0.02)
    for b in (1, 2):
        direct = _table(Ma, Ka, Ca, b)
        assert _rel(planted[b][:, 1:], direct[:, 1:]) < 1e-10
        assert _rel(planted[b][:, 1:], tables[b][:, 1:]) > 1e-2     # it did change the test


def test_added_mass_in_both_tests_equals_the_direct_solve():
    mod = _load("make_planted_joint")
    M, K, C = _frame()
    tables = {1: _table(M, K, C, 1), 2: _table(M, K, C, 2)}
    planted = mod.plant(tables, CASE, {"family": "added_mass", "location": {"floor": 2},
                                       "size": {"dm_kg": 1.3}})
    M2 = M.copy()
    M2[1, 1] += 1.3
    for b in (1, 2):
        assert _rel(planted[b][:, 1:], _table(M2, K, C, b)[:, 1:]) < 1e-10


def test_a_sensor_error_is_the_same_in_both_tests_and_on_its_channel_only():
    mod = _load("make_planted_joint")
    M, K, C = _frame()
    tables = {1: _table(M, K, C, 1), 2: _table(M, K, C, 2)}
    col = 1 + 2                                  # floor1 is data column 2
    g = mod.plant(tables, CASE, {"family": "sensor_gain", "location": {"channel": "floor1"},
                                 "size": {"gain": 1.1}})
    d = mod.plant(tables, CASE, {"family": "sensor_delay", "location": {"channel": "floor1"},
                                 "size": {"delay_ms": 2.0}})
    for b in (1, 2):
        assert np.allclose(g[b][:, col], 1.1 * tables[b][:, col], rtol=1e-14, atol=0)
        assert np.allclose(d[b][:, col], tables[b][:, col] * np.exp(-1j * W * 2e-3),
                           rtol=1e-14, atol=0)
        others = [c for c in range(4) if c != col]
        assert np.array_equal(g[b][:, others], tables[b][:, others])
        assert np.array_equal(d[b][:, others], tables[b][:, others])


def test_a_floor_no_test_drives_is_refused():
    mod = _load("make_planted_joint")
    M, K, C = _frame()
    tables = {1: _table(M, K, C, 1), 2: _table(M, K, C, 2)}
    with pytest.raises(ValueError, match="floor 3"):
        mod.plant(tables, CASE, {"family": "added_mass", "location": {"floor": 3},
                                 "size": {"dm_kg": 1.0}})
