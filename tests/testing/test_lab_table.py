"""Table- and shaker-structure interaction (nlp/testing/lab/table.py): the stiff-actuator
limit, the base reaction against a single-storey closed form, and the force cell."""

import numpy as np

from nlp.testing.blind.simulators import newmark
from nlp.testing.frames import shear_K
from nlp.testing.lab.table import (cell_force, command_force, table_transfer, with_shaker,
                                   with_table)

FS = 2000.0


def _structure():
    M = np.diag([4.0, 3.0, 2.0])
    K = shear_K([3000.0, 2500.0, 2000.0])
    return M, 0.2 * M + 1e-3 * K, K


def test_infinitely_stiff_actuator_reproduces_the_drive():
    # x_t / x_c = 1 + w^2 m_dyn(w) / k_a + O(k_a^-2) (m_dyn: the platen and the structure's
    # dynamic mass): the table's error falls as f_a^-2
    M, C, K = _structure()
    t = np.arange(0, 12, 1 / FS)
    a_c = np.sin(2 * np.pi * 2.0 * t) * np.exp(-((t - 5) / 1.5) ** 2)
    m_t, m_all = 10.0, 19.0
    errs = []
    for f_a in (40.0, 160.0):
        k_a = m_all * (2 * np.pi * f_a) ** 2
        c_a = 2 * 0.5 * m_all * 2 * np.pi * f_a
        Ma, Ca, Ka, _ = with_table(M, C, K, np.zeros_like(K), np.ones(3), m_t, k_a, c_a)
        b = np.zeros(4)
        b[-1] = 1.0
        a = newmark(Ma, Ca, Ka, b, command_force(a_c, FS, 0.2, k_a, c_a), 1 / FS)[2]
        errs.append(np.max(np.abs(a[-1] - a_c)) / np.max(np.abs(a_c)))
    assert 8 < errs[0] / errs[1] < 32                     # (160/40)^2 = 16
    assert errs[1] < 5e-3
    assert np.allclose(table_transfer(M, C, K, np.ones(3), 10.0, 1e12, 0.0, [1.0, 5.0, 20.0]), 1.0,
                       atol=1e-6)


def test_base_reaction_matches_the_single_storey_closed_form():
    # x_t / x_c = (k_a + j w c_a) / (k_a + j w c_a - w^2 m_t - w^2 m T), with the storey's
    # absolute transmissibility T = (k + j w c) / (k + j w c - w^2 m)
    m, k, c = 5.0, 4000.0, 3.0
    m_t, k_a, c_a = 8.0, 2.0e5, 400.0
    f = np.array([0.5, 3.0, np.sqrt(k / m) / (2 * np.pi), 12.0])
    w = 2 * np.pi * f
    T = (k + 1j * w * c) / (k + 1j * w * c - w * w * m)
    expect = (k_a + 1j * w * c_a) / (k_a + 1j * w * c_a - w * w * m_t - w * w * m * T)
    got = table_transfer(np.array([[m]]), np.array([[c]]), np.array([[k]]), np.ones(1), m_t, k_a, c_a, f)
    assert np.allclose(got, expect, rtol=1e-10)
    # the table does not reproduce the drive at the structure's resonance: it dips
    assert abs(got[2]) < 0.8 * abs(got[0])


def test_force_cell_reads_what_enters_the_structure_with_its_base_mass():
    M, C, K = _structure()
    sh = {"m_a": 0.3, "k_s": 500.0, "c_s": 20.0, "m_below": 0.05}
    dof = 1
    Ms, Cs, Ks = with_shaker(M, C, K, dof, sh)
    Mb = M.copy()
    Mb[dof, dof] += sh["m_below"]
    e = np.eye(3)[dof]
    for f in (1.0, 4.0, 9.0):
        w = 2 * np.pi * f
        Q = np.linalg.solve(Ks - w * w * Ms + 1j * w * Cs, e)        # unit coil force
        F = cell_force(1.0, Q, 1j * w * Q, -w * w * Q, dof, sh)
        H = -w * w * Q / F
        H_expect = -w * w * np.linalg.solve(K - w * w * Mb + 1j * w * C, e)
        assert np.allclose(H, H_expect, rtol=1e-10)
        assert abs(F - 1.0) > 1e-3                                     # the drive is not the force
