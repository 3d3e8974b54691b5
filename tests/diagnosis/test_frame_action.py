"""Frame action (nlp.diagnosis.families.FrameAction): a shear chain read as a one-bay moment
frame with beam-column stiffness ratio rho, checked against the lab's own frame elements and
against OpenSeesPy (nlp.testing.lab.frames, which shares no code with the family)."""

import casadi as ca
import numpy as np
import pytest

from nlp.diagnosis.families import FrameAction, condensed_dK, frame_action_dK
from nlp.testing.frames import shear_K
from nlp.testing.lab.frames import (beam_EI_for_rho, lateral_K, lateral_K_opensees,
                                    muto_story_k)

H, L = 3.2, 6.0
EI_C = np.array([9.0e6, 8.0e6, 7.0e6, 5.5e6])    # N m^2, per storey (2 columns each)
EI_U = np.full(4, 7.0e6)                         # a uniform frame


def _num(x):
    return np.array(ca.DM(ca.evalf(ca.SX(x))))


def _designer_frame(rho):
    """(the shear chain of Muto's story stiffnesses plus the family's dK, the beams' EI_b)
    of the uniform frame with ratio rho."""
    EI_b = beam_EI_for_rho(rho, EI_U, H, L)
    k = muto_story_k(EI_U, EI_b, H, L, n_cols=2)
    return shear_K(k) + _num(frame_action_dK([float(x) for x in k], 1.0 / rho)), EI_b


@pytest.mark.parametrize("rho", [0.5, 1.0, 2.0, 5.0])
def test_condensed_dK_is_the_condensed_frame(rho):
    """Columns of rigid-beam story stiffness k = 24 EI_c/h^3 (two per storey), any EI_c."""
    K_frame = lateral_K(EI_C, beam_EI_for_rho(rho, EI_C, H, L), H, L, n_cols=2)
    k = 12 * 2 * EI_C / H**3
    K = shear_K(k) + _num(condensed_dK([float(x) for x in k], 1.0 / rho))
    np.testing.assert_allclose(K, K_frame, rtol=1e-9, atol=1e-9 * np.abs(K_frame).max())


@pytest.mark.parametrize("rho", [0.5, 1.0, 2.0, 5.0])
def test_the_family_turns_muto_story_stiffnesses_into_the_frame(rho):
    """A designer's shear model of a uniform frame (Muto's D-values, the lab's own formula):
    the chain plus the family's dK is the frame's condensed stiffness."""
    K, EI_b = _designer_frame(rho)
    K_frame = lateral_K(EI_U, EI_b, H, L, n_cols=2)
    np.testing.assert_allclose(K, K_frame, rtol=1e-9, atol=1e-9 * np.abs(K_frame).max())


def test_against_opensees():
    pytest.importorskip("openseespy.opensees")
    K, EI_b = _designer_frame(0.8)
    K_ops = lateral_K_opensees(EI_U, EI_b, H, L, n_cols=2)
    np.testing.assert_allclose(K, K_ops, rtol=1e-5, atol=1e-5 * np.abs(K_ops).max())


def test_rigid_beams_are_the_shear_frame_and_flexible_beams_couple_every_floor():
    k = [float(x) for x in 12 * 2 * EI_C / H**3]
    assert np.abs(_num(frame_action_dK(k, 0.0))).max() == 0.0
    dK = _num(condensed_dK(k, 1.0))
    # floors two or more apart: the shear chain has zeros there, the frame does not
    assert abs(dK[0, 2]) > 1e-3 * k[0] and abs(dK[0, 3]) > 1e-4 * k[0]
    # softer than the columns' rigid-beam chain: dK is negative semi-definite
    assert np.linalg.eigvalsh(0.5 * (dK + dK.T)).max() < 1e-9 * k[0]


def test_the_family_reads_the_story_stiffnesses_from_the_model():
    EI_b = beam_EI_for_rho(1.5, EI_U, H, L)
    k = muto_story_k(EI_U, EI_b, H, L, n_cols=2)
    parts = [ca.DM(shear_K(np.where(np.arange(4) == r, k, 0.0))) for r in range(4)]
    out = FrameAction().apply({"K": ca.SX(shear_K(k))}, ca.SX([1.0 / 1.5]), {"K_parts": parts})
    K_frame = lateral_K(EI_U, EI_b, H, L, n_cols=2)
    np.testing.assert_allclose(_num(out["K"]), K_frame, rtol=1e-9,
                               atol=1e-9 * np.abs(K_frame).max())


def test_after_an_appended_dof_the_frame_acts_on_the_floors_only():
    """With an appendage's DOF already appended (K is 5 x 5 on a 4-storey frame), frame
    action changes the floors' block as on the bare frame and leaves the appended row and
    column alone."""
    EI_b = beam_EI_for_rho(1.5, EI_U, H, L)
    k = muto_story_k(EI_U, EI_b, H, L, n_cols=2)
    parts = [ca.DM(shear_K(np.where(np.arange(4) == r, k, 0.0))) for r in range(4)]
    K5 = np.zeros((5, 5))
    K5[:4, :4] = shear_K(k)
    K5[3, 3] += 50.0
    K5[3, 4] = K5[4, 3] = -50.0
    K5[4, 4] = 50.0
    out = _num(FrameAction().apply({"K": ca.SX(K5)}, ca.SX([1.0 / 1.5]), {"K_parts": parts})["K"])
    expected = K5.copy()
    expected[:4, :4] += lateral_K(EI_U, EI_b, H, L, n_cols=2) - shear_K(k)
    np.testing.assert_allclose(out, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
