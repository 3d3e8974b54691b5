"""simulate() against scipy.signal.lsim and against the exact steady-state FRF."""

import numpy as np
import pytest
from scipy import signal

from nlp.errors import InputError
from nlp.frf.simulate import simulate


def _system(seed=0):
    """Random 3-DOF shear frame with non-proportional damping."""
    rng = np.random.default_rng(seed)
    m = rng.uniform(1.0, 3.0, 3)
    k = rng.uniform(2e3, 6e3, 3)
    M = np.diag(m)
    K = np.array([[k[0] + k[1], -k[1], 0], [-k[1], k[1] + k[2], -k[2]], [0, -k[2], k[2]]])
    R = rng.normal(size=(3, 3))
    C = 0.5 * R @ R.T + np.diag([5.0, 0.0, 0.0])  # a dashpot at DOF 0 only: not Rayleigh
    return M, C, K


def _lsim_reference(M, C, K, b, u, t):
    """Independent state-space model (x = [q; v]) integrated by scipy.signal.lsim."""
    n = M.shape[0]
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    B = np.concatenate([np.zeros(n), b])[:, None]
    Cout = np.eye(2 * n)
    _, _, x = signal.lsim((A, B, Cout, np.zeros((2 * n, 1))), u, t, interp=True)
    return x[:, :n].T, x[:, n:].T, A[n:] @ x.T


def test_system_is_not_proportionally_damped():
    M, C, K = _system()
    Mi = np.linalg.inv(M)
    # proportional (classical) damping <=> C M^-1 K symmetric (Caughey & O'Kelly)
    P = C @ Mi @ K
    assert np.linalg.norm(P - P.T) > 1e-3 * np.linalg.norm(P)


@pytest.mark.parametrize("kind", ["ground", "force"])
def test_matches_lsim(kind):
    M, C, K = _system()
    fs, n = 200.0, 2000
    t = np.arange(n) / fs
    u = np.random.default_rng(1).normal(size=n)
    if kind == "ground":
        b = -np.ones(3)  # M^-1 (-M 1)
        r = simulate(M, C, K, u, fs, input="ground")
    else:
        b = np.linalg.solve(M, np.array([0.0, 1.0, 0.0]))
        r = simulate(M, C, K, u, fs, input="force", dof=1)
    q, v, qdd = _lsim_reference(M, C, K, b, u, t)
    a_expected = qdd + (0.0 if kind == "ground" else b[:, None] * u)  # absolute: q'' + a_g
    np.testing.assert_allclose(r.t, t)
    for got, ref in ((r.q, q), (r.v, v), (r.a, a_expected)):
        assert got.shape == (3, n)
        assert np.max(np.abs(got - ref)) <= 1e-9 * np.max(np.abs(ref))


def _frf(M, C, K, b, w):
    """Exact receptance (K - w^2 M + j w C)^-1 b at one frequency [rad/s]."""
    return np.linalg.solve(K - w**2 * M + 1j * w * C, b)


@pytest.mark.parametrize("kind", ["ground", "force"])
def test_steady_sine_matches_frf(kind):
    M, C, K = _system()
    fs, f0 = 1000.0, 9.0
    w = 2 * np.pi * f0
    t = np.arange(int(30 * fs)) / fs
    u = np.cos(w * t)
    if kind == "ground":
        Hq = _frf(M, C, K, -M @ np.ones(3), w)
        Ha = 1.0 + (-(w**2)) * Hq  # absolute accelerance = 1 + (-w^2) H_rel
        r = simulate(M, C, K, u, fs)
    else:
        Hq = _frf(M, C, K, np.array([0.0, 0.0, 1.0]), w)
        Ha = -(w**2) * Hq
        r = simulate(M, C, K, u, fs, input="force", dof=2)
    tail = t > 25.0  # transients (slowest time constant 3.2 s here) have died out
    ph = np.exp(1j * w * t[tail])
    for got, H in ((r.q, Hq), (r.v, 1j * w * Hq), (r.a, Ha)):
        expected = np.real(H[:, None] * ph)  # response to Re(e^{jwt}) is Re(H e^{jwt})
        err = np.max(np.abs(got[:, tail] - expected)) / np.max(np.abs(H))
        assert err < 2e-3


def test_bad_inputs():
    M, C, K = _system()
    with pytest.raises(InputError, match="dof"):
        simulate(M, C, K, np.zeros(10), 100.0, input="force", dof=3)
    with pytest.raises(InputError, match="input"):
        simulate(M, C, K, np.zeros(10), 100.0, input="base")
    with pytest.raises(InputError, match="'u'"):
        simulate(M, C, K, np.array([0.0, np.nan]), 100.0)
    with pytest.raises(InputError, match="'K'"):
        simulate(M, C, K[:2, :2], np.zeros(10), 100.0)
