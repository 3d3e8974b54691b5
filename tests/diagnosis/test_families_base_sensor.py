"""A sensor on the base (floor 0): the same meaning in `run` and `diagnose`.

Fixed base: its absolute acceleration is the ground input (accelerance 1).
Flexible base (the base_flexibility family): the base DOF's absolute
acceleration, checked against an independent 4-DOF model written here.
"""

import numpy as np
import pytest
import yaml

from support.frames import frame_parameter_set, shear_K
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.diagnosis.families import BaseFlexibility, extend_parameters, references
from nlp.errors import InputError
from nlp.frf.reference import BASE_DOF, channel_frfs
from nlp.model.damping import GeneralDamping
from nlp.model.nominal import shear_frame
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem

M_FL = np.array([5.0, 4.5, 4.0])
K_ST = np.array([4000.0, 3200.0, 2600.0])
C_ST = np.array([3.0, 2.0, 1.5])          # story dashpots [N s/m]


def _case(tmp_path, f, H, floors, excitation=None, output="absolute_accelerance",
          backend="auto"):
    np.savez(tmp_path / "frf.npz", f=f, H=H)
    case = {"name": "base", "model": {"type": "shear_frame", "masses": M_FL.tolist(),
                                      "stiffnesses": K_ST.tolist(), "frf_backend": backend},
            "parameters": {"fixed": {"m1": float(M_FL[0])}},
            "damping": {"model": "general", "matrix": shear_K(C_ST).tolist()},
            "data": {"file": "frf.npz", "window": "none",
                     "channels": [{"name": f"a{fl}", "floor": fl, "output": output, "column": i}
                                  for i, fl in enumerate(floors)]},
            "frequencies": {"method": "all"}}
    if excitation:
        case["excitation"] = excitation
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(case))
    return str(tmp_path / "case.yaml")


def _flexible_base_frf(f, m_b, k_b, c_b):
    """Absolute accelerances of floors 1-3 and of the base, under ground acceleration,
    for the frame standing on a base mass m_b held by a spring k_b and a dashpot c_b.
    DOFs relative to the ground: floors 1-3, then the base; story 1 joins floor 1
    and the base."""
    n = 4
    M = np.diag(np.concatenate([M_FL, [m_b]]))

    def assemble_springs(story, ground):
        A = np.zeros((n, n))
        A[:3, :3] = shear_K(story)
        A[0, 3] = A[3, 0] = -story[0]
        A[3, 3] = story[0] + ground
        return A

    K, C = assemble_springs(K_ST, k_b), assemble_springs(C_ST, c_b)
    out = np.empty((n, f.size), complex)
    for i, fk in enumerate(f):
        w = 2 * np.pi * fk
        q = np.linalg.solve(K - w**2 * M + 1j * w * C, -M @ np.ones(n))
        out[:, i] = -w**2 * q + 1.0
    return out


@pytest.mark.parametrize("backend", ["dense", "sparse"])
def test_fixed_base_sensor_reads_the_input(tmp_path, backend):
    f = np.linspace(0.5, 12.0, 300)
    H = np.ones((4, f.size), complex)           # placeholder data: only the model is checked
    H[:3] = 1.0 + 0.5j
    case = assemble(load_case(_case(tmp_path, f, H, [1, 2, 3, 0], backend=backend)))
    assert case.channels[3].dof == BASE_DOF
    M, K = np.diag(M_FL), shear_K(K_ST)
    Ha = channel_frfs(M, shear_K(C_ST), K, 2 * np.pi * f, case.channels)
    np.testing.assert_allclose(Ha[3], 1.0)
    # the symbolic FRF of the NLP agrees
    pr = build_problem(case)
    Hs = pr.channel_frfs(pr.z0, 2 * np.pi * f)
    np.testing.assert_allclose(Hs, Ha, rtol=1e-9, atol=1e-12)


def test_flexible_base_sensor_is_the_base_dof(tmp_path):
    m_b, k_b, c_b = 3.0, 20000.0, 4.0
    f = np.linspace(0.5, 15.0, 400)
    H = _flexible_base_frf(f, m_b, k_b, c_b)     # rows: floors 1-3, base
    case = assemble(load_case(_case(tmp_path, f, H, [1, 2, 3, 0])))
    refs = references(case.model, case.damping.C0)
    e = BaseFlexibility()
    params = extend_parameters(case.params, [e], refs, values=[[m_b, np.log10(k_b), c_b]])
    pr = UpdatingProblem(case.model, case.damping, params, case.target, enrichments=[e], refs=refs)
    Ha = pr.channel_frfs(pr.z0, 2 * np.pi * f)
    np.testing.assert_allclose(Ha, H, rtol=1e-8)


@pytest.mark.parametrize("excitation,output", [({"type": "force", "floor": 1}, "accelerance"),
                                               (None, "receptance")])
def test_base_sensor_needs_absolute_acceleration_under_ground_input(tmp_path, excitation, output):
    f = np.linspace(0.5, 12.0, 50)
    path = _case(tmp_path, f, np.ones((2, f.size), complex), [1, 0], excitation, output)
    with pytest.raises(InputError, match=r"floor"):
        assemble(load_case(path))


def test_negative_floor_is_refused(tmp_path):
    f = np.linspace(0.5, 12.0, 50)
    path = _case(tmp_path, f, np.ones((2, f.size), complex), [1, -1])
    with pytest.raises(InputError, match=r"data.channels\[1\].floor"):
        load_case(path)


def _base_over_table(w, m, k, c, m_b, k_b, c_b):
    """Hand-derived base/table transfer function of a 2-storey frame on a flexible base.

    The frame above the base is a chain: floor 2 (m2) on story 2 (k2 + i w c2) has the
    dynamic stiffness Z2 = -w^2 m2 k2' / (k2' - w^2 m2); floor 1 adds -w^2 m1, and story 1
    in series gives Z1 = k1' Z / (k1' + Z). The base mass m_b on k_b' = k_b + i w c_b then
    obeys (k_b' - w^2 m_b + Z1) X_b = k_b' X_g, and absolute accelerations are in the
    ratio of absolute displacements: a_b / a_g = X_b / X_g.
    """
    k1, k2 = k[0] + 1j * w * c[0], k[1] + 1j * w * c[1]
    Z2 = -w**2 * m[1] * k2 / (k2 - w**2 * m[1])
    Z = -w**2 * m[0] + Z2
    Z1 = k1 * Z / (k1 + Z)
    kb = k_b + 1j * w * c_b
    return kb / (kb - w**2 * m_b + Z1)


def test_two_storey_base_channel_is_the_hand_derived_base_over_table():
    """Channel a0 (floor 0) of the BaseFlexibility model equals the closed-form a_b/a_g of
    a 2-storey frame on a base mass, spring and dashpot; the rigid-base model reads 1."""

    m, k, c = np.array([4.0, 3.0]), np.array([3000.0, 2400.0]), np.array([2.0, 1.5])
    m_b, k_b, c_b = 2.5, 9000.0, 12.0
    w = 2 * np.pi * np.linspace(0.3, 12.0, 120)
    model, damping = shear_frame(m, k), GeneralDamping(shear_K(c))
    rigid_params = frame_parameter_set(m, k, damping)
    chans = (Channel("a0", BASE_DOF, "absolute_accelerance"),
             Channel("a1", 0, "absolute_accelerance"))
    tg = Target(w, np.ones((2, w.size), complex), np.ones((2, w.size)), chans, "ground")
    refs = {"m_ref": 3.5, "k_ref": 2700.0, "c_ref": 1.75}
    e = BaseFlexibility()
    params = extend_parameters(rigid_params, [e], refs,
                               [[m_b, np.log10(k_b), c_b]])
    pr = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                         enrichments=[e], refs=refs)
    H = pr.channel_frfs(pr.z0, w)
    expected = _base_over_table(w, m, k, c, m_b, k_b, c_b)
    np.testing.assert_allclose(H[0], expected, rtol=1e-9)
    assert np.max(np.abs(np.abs(expected) - 1.0)) > 0.5      # the base visibly moves
    rigid = UpdatingProblem(model, damping, rigid_params, tg,
                            solver=SolverConfig(compile=False))
    np.testing.assert_allclose(rigid.channel_frfs(rigid.z0, w)[0], 1.0)
