"""Frame action (nlp.diagnosis.families.FrameAction): the shear chain plus dK(1/rho) is the
condensed stiffness of a one-bay moment frame with beam-column stiffness ratio rho, checked
against the lab's own frame elements and against OpenSeesPy."""

import casadi as ca
import numpy as np
import pytest

from nlp.diagnosis.families import FrameAction, frame_action_dK
from nlp.testing.frames import shear_K
from nlp.testing.lab.frames import beam_EI_for_rho, lateral_K, lateral_K_opensees

H, L = 3.2, 6.0
EI_C = np.array([9.0e6, 8.0e6, 7.0e6, 5.5e6])    # N m^2, per storey (2 columns each)


def _shear_and_dK(rho):
    k = 12 * 2 * EI_C / H**3                     # the rigid-beam story stiffness
    dK = np.array(ca.DM(frame_action_dK([float(x) for x in k], 1.0 / rho)))
    return shear_K(k), dK


@pytest.mark.parametrize("rho", [0.5, 1.0, 2.0, 5.0])
def test_shear_chain_plus_dK_is_the_condensed_frame(rho):
    K_frame = lateral_K(EI_C, beam_EI_for_rho(rho, EI_C, H, L), H, L, n_cols=2)
    Ks, dK = _shear_and_dK(rho)
    np.testing.assert_allclose(Ks + dK, K_frame, rtol=1e-9, atol=1e-9 * np.abs(K_frame).max())


def test_against_opensees():
    pytest.importorskip("openseespy.opensees")
    rho = 0.8
    K_ops = lateral_K_opensees(EI_C, beam_EI_for_rho(rho, EI_C, H, L), H, L, n_cols=2)
    Ks, dK = _shear_and_dK(rho)
    np.testing.assert_allclose(Ks + dK, K_ops, rtol=1e-5, atol=1e-5 * np.abs(K_ops).max())


def test_rigid_beams_are_the_shear_frame_and_flexible_beams_couple_every_floor():
    Ks, dK0 = _shear_and_dK(np.inf)
    assert np.abs(dK0).max() == 0.0
    _, dK = _shear_and_dK(1.0)
    # floors two or more apart: the shear chain has zeros there, the frame does not
    assert abs(dK[0, 2]) > 1e-3 * Ks[0, 0] and abs(dK[0, 3]) > 1e-4 * Ks[0, 0]
    # softer than the shear frame: dK is negative semi-definite
    assert np.linalg.eigvalsh(0.5 * (dK + dK.T)).max() < 1e-9 * Ks[0, 0]


def test_the_family_reads_the_story_stiffnesses_from_the_model():
    k = 12 * 2 * EI_C / H**3
    parts = [ca.DM(shear_K(np.where(np.arange(4) == r, k, 0.0))) for r in range(4)]
    sys = {"K": ca.SX(shear_K(k))}
    out = FrameAction().apply(sys, ca.SX([1.0 / 1.5]), {"K_parts": parts})
    K_frame = lateral_K(EI_C, beam_EI_for_rho(1.5, EI_C, H, L), H, L, n_cols=2)
    np.testing.assert_allclose(np.array(ca.DM(ca.evalf(out["K"]))), K_frame, rtol=1e-9,
                               atol=1e-9 * np.abs(K_frame).max())
