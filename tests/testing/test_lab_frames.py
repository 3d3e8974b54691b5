"""Frames that are not shear buildings (nlp/testing/lab/frames.py): the condensed
flexible-beam frame against its shear (rho -> infinity) and cantilever (rho = 0) limits
and against OpenSeesPy; the eccentric planar model's decoupling at zero eccentricity."""

import numpy as np
import pytest

from nlp.testing.frames import shear_K
from nlp.testing.lab.frames import (beam_EI_for_rho, cantilever_K, eccentric_model, lateral_K,
                                    lateral_K_opensees, muto_story_k, story_k_from_load)

EI_C = np.array([1.0, 1.2, 0.9, 1.1]) * 100.0
H, L = 1.0, 1.5


@pytest.mark.parametrize("n_cols", [2, 3])
def test_rigid_beams_give_the_shear_frame(n_cols):
    for rho, tol in ((1e3, 5e-3), (1e6, 5e-6)):
        K = lateral_K(EI_C, beam_EI_for_rho(rho, EI_C, H, L, n_cols), H, L, n_cols)
        Ks = shear_K(n_cols * 12 * EI_C / H**3)
        assert np.max(np.abs(K - Ks)) < tol * np.max(np.abs(Ks))
    k = muto_story_k(EI_C, beam_EI_for_rho(1e6, EI_C, H, L, n_cols), H, L, n_cols)
    assert np.allclose(k, n_cols * 12 * EI_C / H**3, rtol=1e-5)


def test_flexible_beams_soften_and_couple_non_adjacent_floors():
    K1 = lateral_K(EI_C, beam_EI_for_rho(1.0, EI_C, H, L), H, L)
    Ks = shear_K(24 * EI_C / H**3)
    assert np.abs(K1[0, 2]) > 0.03 * np.abs(K1[0, 1])
    assert np.all(np.linalg.eigvalsh(Ks - K1) > -1e-9)          # never stiffer than shear


def test_beamless_frame_is_independent_cantilevers():
    EI = np.full(4, 100.0)
    K = lateral_K(EI, np.zeros(4), H, L, 2)
    assert np.allclose(K, 2 * cantilever_K(100.0, H * np.arange(1, 5)), rtol=1e-9)
    # the cantilever's tip flexibility, P L^3 / (3 EI)
    assert np.isclose(np.linalg.inv(cantilever_K(100.0, [1.0, 2.0]))[1, 1], 8.0 / 300.0)


def test_own_elements_agree_with_opensees():
    pytest.importorskip("openseespy")
    for rho in (0.5, 2.0, 5.0):
        EI_b = beam_EI_for_rho(rho, EI_C, H, L)
        Ko, Kw = lateral_K_opensees(EI_C, EI_b, H, L), lateral_K(EI_C, EI_b, H, L)
        assert np.max(np.abs(Ko - Kw)) < 1e-4 * np.max(np.abs(Kw))


def _x_theta_coupling(M, K):
    x, th = np.arange(0, M.shape[0], 3), np.arange(2, M.shape[0], 3)
    return max(np.abs(M[np.ix_(x, th)]).max(), np.abs(K[np.ix_(x, th)]).max())


def test_eccentric_model_without_eccentricity_decouples_torsion():
    m = np.array([4.0, 3.0, 2.0])
    kx = np.array([3000.0, 2500.0, 2000.0])
    M, K = eccentric_model(m, (kx / 2, kx / 2), (kx / 2, kx / 2), (1.5, 1.2), (0.0, 0.0), (0.5, 0.4))
    assert _x_theta_coupling(M, K) == 0.0
    x = np.arange(0, 9, 3)
    w_x = np.sort(np.linalg.eigvals(np.linalg.solve(M[np.ix_(x, x)], K[np.ix_(x, x)])).real)
    w_s = np.sort(np.linalg.eigvals(np.linalg.solve(np.diag(m), shear_K(kx))).real)
    assert np.allclose(w_x, w_s)
    # torsional stiffness of one story: sum k_f d_f^2 over the four frames
    assert np.isclose(K[8, 8], 2 * 1000.0 * 0.4**2 + 2 * 1000.0 * 0.5**2)
    Me, Ke = eccentric_model(m, (kx / 2, kx / 2), (kx / 2, kx / 2), (1.5, 1.2), (0.0, 0.1), (0.5, 0.4))
    assert _x_theta_coupling(Me, Ke) > 0.0


def test_story_stiffnesses_from_a_load_are_exact_for_a_shear_frame_and_for_that_load():
    k = np.array([3000.0, 2500.0, 2000.0])
    load = np.array([1.0, 2.0, 3.0])
    assert np.allclose(story_k_from_load(shear_K(k), load), k)
    K = lateral_K(EI_C[:3], beam_EI_for_rho(0.7, EI_C[:3], H, L), H, L)
    ks = story_k_from_load(K, load)
    assert np.allclose(np.linalg.solve(shear_K(ks), load), np.linalg.solve(K, load))
