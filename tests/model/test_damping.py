"""Damping models: SPD for any parameters, exact initial C, modal ratios."""

import numpy as np

from support.frames import TABLE1_INITIAL_K, TABLE1_INITIAL_M, shear_K, random_system
from nlp.model.damping import GeneralDamping, ModalDamping, RayleighDamping, rayleigh_from_ratios
from nlp.frf.reference import modal_parameters


def test_general_initial_reproduces_C0(rng):
    _, C0, _ = random_system(5, rng)
    d = GeneralDamping(C0)
    np.testing.assert_allclose(d.matrix(d.initial()), C0, rtol=1e-12)


def test_general_is_spd_for_any_parameters(rng):
    _, C0, _ = random_system(4, rng)
    d = GeneralDamping(C0)
    lo, hi = d.default_bounds()
    for _ in range(500):  # anywhere in the box the optimiser may visit
        theta = lo + (hi - lo) * rng.random(lo.size)
        C = d.matrix(theta)
        np.testing.assert_allclose(C, C.T, rtol=0, atol=1e-12 * np.abs(C).max())
        np.linalg.cholesky(C)  # succeeds only for SPD matrices
        assert np.linalg.eigvalsh(C).min() > 0


def test_rayleigh_ratios_at_two_modes():
    M = np.diag(TABLE1_INITIAL_M)
    K = shear_K(TABLE1_INITIAL_K)
    a0, a1 = rayleigh_from_ratios(M, K, 0.02)
    _, zeta, _ = modal_parameters(M, a0 * M + a1 * K, K)
    np.testing.assert_allclose(zeta[[0, -1]], 0.02, rtol=1e-3)
    d = RayleighDamping(a0, a1)
    np.testing.assert_allclose(d.matrix(d.initial(), M, K), a0 * M + a1 * K)


def test_modal_damping_gives_the_ratios():
    M = np.diag(TABLE1_INITIAL_M)
    K = shear_K(TABLE1_INITIAL_K)
    zeta = np.array([0.01, 0.02, 0.03, 0.015])
    C = ModalDamping(M, K, zeta).matrix(zeta)
    _, z, _ = modal_parameters(M, C, K)
    np.testing.assert_allclose(z, zeta, rtol=1e-9)
