"""The lab's nonlinear links and their integrator (nlp/testing/lab/effects.py) against
closed-form answers: a linear limit, homogeneity of the bilinear crack, the bilinear
period, the Coulomb decrement, a sliding mass that sticks, and an independent ODE solver."""

import numpy as np

from nlp.testing.blind.simulators import newmark
from nlp.testing.frames import shear_K
from nlp.testing.lab.effects import G, crack_equivalent, newmark_links, simulate_links
from nlp.testing.lab.links import sliding_mass

H = 1 / 1000


def _system():
    M = np.diag([4.0, 3.0, 2.0])
    K = shear_K([3000.0, 2500.0, 2000.0])
    return M, 0.2 * M + 1e-3 * K, K


def _pulse(t, f=3.0, at=1.2, width=0.4):
    return np.sin(2 * np.pi * f * t) * np.exp(-((t - at) / width) ** 2)


def test_crack_with_equal_stiffnesses_is_the_linear_system():
    M, C, K = _system()
    b = -M @ np.ones(3)
    t = np.arange(0, 3, H)
    u = _pulse(t)
    lk = {"kind": "crack", "i": 0, "j": 1, "delta": 0.0, "k": 2500.0}
    q = newmark_links(M, C, K, b, u, H, [lk])[0]
    assert np.max(np.abs(q - newmark(M, C, K, b, u, H)[0])) < 1e-12


def test_crack_is_positively_homogeneous_but_not_linear():
    M, C, K = _system()
    b = np.array([1.0, 0.0, 0.0])
    t = np.arange(0, 3, H)
    u = 20 * _pulse(t)
    lk = {"kind": "crack", "i": None, "j": 0, "delta": 0.3, "k": 3000.0}
    q1 = newmark_links(M, C, K, b, u, H, [lk])[0]
    q2 = newmark_links(M, C, K, b, 2.5 * u, H, [lk])[0]
    qm = newmark_links(M, C, K, b, -u, H, [lk])[0]
    scale = np.max(np.abs(q1))
    assert np.max(np.abs(q2 - 2.5 * q1)) < 1e-6 * 2.5 * scale          # scales with a > 0
    assert np.max(np.abs(qm + q1)) > 0.05 * scale                       # but not with -1


def test_bilinear_oscillator_period_matches_the_two_half_cycles():
    m, k, delta = 2.0, 800.0, 0.36
    M, K, C = np.array([[m]]), np.array([[k]]), np.zeros((1, 1))
    t = np.arange(0, 4, H / 2)
    u = np.zeros(t.size)
    u[1:3] = 1e3                                  # an impulse, then free vibration
    lk = {"kind": "crack", "i": None, "j": 0, "delta": delta, "k": k}
    q = newmark_links(M, C, K, np.array([1.0]), u, H / 2, [lk])[0][0]
    up = np.flatnonzero((q[:-1] < 0) & (q[1:] >= 0))[1:]
    T = np.mean(np.diff(t[up]))
    w1 = np.sqrt(k / m)
    assert abs(T - (np.pi / w1 + np.pi / (w1 * np.sqrt(1 - delta)))) < 2e-3 * T
    assert np.isclose(crack_equivalent(delta), (2 * np.pi / T) ** 2 / w1**2, rtol=5e-3)


def test_coulomb_friction_decays_by_four_Fc_over_k_per_cycle():
    m, k, Fc = 1.0, 400.0, 0.8
    M, K, C = np.array([[m]]), np.array([[k]]), np.zeros((1, 1))
    t = np.arange(0, 3, H / 2)
    u = np.zeros(t.size)
    u[1:3] = 2e3
    lk = {"kind": "friction", "i": None, "j": 0, "F_c": Fc, "v0": 1e-5}
    q = newmark_links(M, C, K, np.array([1.0]), u, H / 2, [lk])[0][0]
    peaks = [q[i] for i in range(1, q.size - 1) if q[i] > q[i - 1] and q[i] >= q[i + 1] and q[i] > 0.02]
    drops = -np.diff(peaks[:4])
    assert np.allclose(drops, 4 * Fc / k, rtol=0.02)


def test_links_integrator_agrees_with_an_independent_ode_solver():
    M, C, K = _system()
    b = -M @ np.ones(3)
    t = np.arange(0, 3, H)
    u = 8 * _pulse(t)
    links = [{"kind": "cubic", "i": None, "j": 0, "k3": 4e6},
             {"kind": "friction", "i": 0, "j": 1, "F_c": 1.5, "v0": 2e-3},
             {"kind": "contact", "i": 1, "j": 2, "k_c": 800.0, "gap": 2e-3}]
    qa = newmark_links(M, C, K, b, u, H, links)[0]
    qb = simulate_links(M, C, K, b, u, H, links)[0]
    assert np.max(np.abs(qa - qb)) < 2e-3 * np.max(np.abs(qb))
    assert np.max(np.abs(qa - newmark(M, C, K, b, u, H)[0])) > 0.02 * np.max(np.abs(qb))


def test_sliding_mass_below_mu_g_moves_with_its_floor():
    M, C, K = _system()
    t = np.arange(0, 3, H)
    u = 0.5 * _pulse(t)
    b = -M @ np.ones(3)
    a_lin = newmark(M, C, K, b, u, H)[2] + u
    peak = np.max(np.abs(a_lin[2]))
    rng = np.random.default_rng(0)
    Mn, Cn, Kn, lk = sliding_mass(rng, M, C, K, 3, 0.2, peak, 2.0, 12.0)
    assert np.isclose(np.trace(Mn), np.trace(M)) and lk["mu"] * G >= peak
    q = newmark_links(Mn, Cn, Kn, -Mn @ np.ones(4), u, H, [lk])[0]
    q_lin = newmark(M, C, K, b, u, H)[0]
    assert np.max(np.abs(q[:3] - q_lin)) < 0.01 * np.max(np.abs(q_lin))
    # at 3x the level it slips: the floor no longer carries the whole mass
    q3 = newmark_links(Mn, Cn, Kn, -Mn @ np.ones(4), 3 * u, H, [lk])[0]
    assert np.max(np.abs(q3[:3] - 3 * q_lin)) > 0.03 * np.max(np.abs(3 * q_lin))
