"""Every added-physics family's FRF against an independent numpy implementation."""

import numpy as np
import pytest

from support.frames import frame_parameter_set, shear_K
from nlp.model.damping import GeneralDamping, RayleighDamping
from nlp.model.nominal import shear_frame
from nlp.diagnosis.families import (AddedMass, BaseFlexibility, HystereticDamping, LocalDamper,
                         ExtraMode, NonadjacentCoupling, SecondaryOscillator, SensorDelay,
                         SensorGain,
                         extend_parameters)
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem

m = np.array([3.0, 2.5, 2.0])
k = np.array([3000.0, 2500.0, 2000.0])
C0 = 0.002 * shear_K(k) + 0.1 * np.diag(m)
REF = {"m_ref": 2.5, "k_ref": 2500.0, "c_ref": 2.0}
W = np.linspace(2.0, 90.0, 40)


def _numpy_frf(M, C, K, Kh, excitation, dof=None):
    n = M.shape[0]
    b = -M @ np.ones(n) if excitation == "ground" else np.eye(n)[dof]
    return np.array([np.linalg.solve(K - w**2 * M + 1j * (w * C + Kh), b) for w in W]).T


def _problem(enrichment, values, excitation="ground", outputs=("receptance",) * 3,
             damping=None):
    model = shear_frame(m, k)
    damping = GeneralDamping(C0) if damping is None else damping
    params = extend_parameters(frame_parameter_set(m, k, damping), [enrichment], REF, [values])
    chans = tuple(Channel(f"c{i + 1}", i, o) for i, o in enumerate(outputs))
    tg = Target(W, np.ones((3, W.size), complex), np.ones((3, W.size)), chans, excitation,
                None if excitation == "ground" else 0)
    pr = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                         enrichments=[enrichment], refs=REF)
    return pr.channel_frfs(pr.z0, W)


def _base():
    return np.diag(m).astype(float), C0.copy(), shear_K(k), np.zeros((3, 3))


def test_added_mass():
    M, C, K, Kh = _base()
    M[1, 1] += 0.4
    np.testing.assert_allclose(_problem(AddedMass(2), [0.4]), _numpy_frf(M, C, K, Kh, "ground"),
                               rtol=1e-9)


def test_base_flexibility():
    M, C, K, Kh = _base()
    mb, kb, cb = 1.5, 2e4, 3.0
    Ma = np.diag([*m, mb])
    Ka = np.zeros((4, 4))
    Ka[:3, :3] = K
    Ka[0, 3] = Ka[3, 0] = -k[0]       # story 1 now joins floor 1 and the base
    Ka[3, 3] = k[0] + kb
    Ca = np.zeros((4, 4))
    Ca[:3, :3] = C
    g = C @ np.ones(3)
    Ca[:3, 3] = Ca[3, :3] = -g
    Ca[3, 3] = g.sum() + cb
    H = _numpy_frf(Ma, Ca, Ka, np.zeros((4, 4)), "ground")[:3]
    np.testing.assert_allclose(_problem(BaseFlexibility(), [mb, np.log10(kb), cb]), H, rtol=1e-9)


def test_base_flexibility_under_rayleigh_damping_extends_the_law_over_the_base():
    """With C = a0 M + a1 K the base joins the model and the law covers it, as an FE
    program assembles a model with its foundation: C = a0 M_b + a1 K_b of the augmented
    matrices, plus the base's own dashpot c_b. The mass-proportional part therefore stays
    on the motion relative to the ground, unlike a general C, which moves with the base."""
    a0, a1 = 0.8, 0.0015
    mb, kb, cb = 1.5, 2e4, 3.0
    Ma = np.diag([*m, mb])
    Ka = np.zeros((4, 4))
    Ka[:3, :3] = shear_K(k)
    Ka[0, 3] = Ka[3, 0] = -k[0]
    Ka[3, 3] = k[0] + kb
    Ca = a0 * Ma + a1 * Ka
    Ca[3, 3] += cb
    H = _numpy_frf(Ma, Ca, Ka, np.zeros((4, 4)), "ground")[:3]
    got = _problem(BaseFlexibility(), [mb, np.log10(kb), cb], damping=RayleighDamping(a0, a1))
    np.testing.assert_allclose(got, H, rtol=1e-9)
    # the general form (all of C through the base) is a different structure here
    g = (a0 * np.diag(m) + a1 * shear_K(k)) @ np.ones(3)
    Cg = np.zeros((4, 4))
    Cg[:3, :3] = a0 * np.diag(m) + a1 * shear_K(k)
    Cg[:3, 3] = Cg[3, :3] = -g
    Cg[3, 3] = g.sum() + cb
    assert np.abs(got / _numpy_frf(Ma, Cg, Ka, np.zeros((4, 4)), "ground")[:3] - 1).max() > 0.01


def test_secondary_oscillator():
    M, C, K, Kh = _base()
    mu, fs, zs = 0.05, 6.0, 0.03
    ms = mu * REF["m_ref"]
    ks, cs = ms * (2 * np.pi * fs) ** 2, 2 * zs * ms * 2 * np.pi * fs
    Ma = np.diag([*m, ms])
    Ka = np.zeros((4, 4))
    Ka[:3, :3] = K
    Ca = np.zeros((4, 4))
    Ca[:3, :3] = C
    for A, v in ((Ka, ks), (Ca, cs)):
        A[2, 2] += v
        A[2, 3] = A[3, 2] = -v
        A[3, 3] = v
    H = _numpy_frf(Ma, Ca, Ka, np.zeros((4, 4)), "ground")[:3]
    np.testing.assert_allclose(_problem(SecondaryOscillator(3, fs), [mu, fs, zs]), H, rtol=1e-9)


@pytest.mark.parametrize("i,j", [(1, 0), (3, 1)])
def test_local_damper(i, j):
    M, C, K, Kh = _base()
    c = 2.5
    e = np.zeros(3)
    e[i - 1] += 1
    if j:
        e[j - 1] -= 1
    H = _numpy_frf(M, C + c * np.outer(e, e), K, Kh, "ground")
    np.testing.assert_allclose(_problem(LocalDamper(i, j), [c]), H, rtol=1e-9)


def test_hysteretic_damping_global_and_story():
    M, C, K, Kh = _base()
    np.testing.assert_allclose(_problem(HystereticDamping(), [0.03]),
                               _numpy_frf(M, C, K, 0.03 * K, "ground"), rtol=1e-9)
    K2 = shear_K(k * np.array([0, 1, 0]))
    np.testing.assert_allclose(_problem(HystereticDamping(2), [0.05]),
                               _numpy_frf(M, C, K, 0.05 * K2, "ground"), rtol=1e-9)


def test_nonadjacent_coupling():
    M, C, K, Kh = _base()
    e = np.array([1.0, 0.0, -1.0])
    np.testing.assert_allclose(_problem(NonadjacentCoupling(1, 3), [400.0]),
                               _numpy_frf(M, C, K + 400.0 * np.outer(e, e), Kh, "ground"),
                               rtol=1e-9)


def test_sensor_gain_and_delay_on_one_channel():
    M, C, K, Kh = _base()
    H = _numpy_frf(M, C, K, Kh, "force", 0) * (-(W**2))
    out = ("accelerance",) * 3
    G = _problem(SensorGain("c2"), [0.1], "force", out)
    np.testing.assert_allclose(G[[0, 2]], H[[0, 2]], rtol=1e-9)
    np.testing.assert_allclose(G[1], 1.1 * H[1], rtol=1e-9)
    D = _problem(SensorDelay("c3"), [4.0], "force", out)
    np.testing.assert_allclose(D[2], H[2] * np.exp(-1j * W * 4e-3), rtol=1e-9)
    np.testing.assert_allclose(np.abs(D[2]), np.abs(H[2]), rtol=1e-12)


def test_extra_mode_adds_a_modal_term_in_each_channels_output():
    """Model discrepancy (ExtraMode): each channel gains a_c L_c (j w / w_x)^p w_x^2 /
    (w_x^2 - w^2 + 2 j zeta w_x w), written out here in complex numpy."""
    M, C, K, Kh = _base()
    Hr = _numpy_frf(M, C, K, Kh, "force", 0)
    out = ("receptance", "mobility", "accelerance")
    p = np.array([0, 1, 2])
    H = Hr * (1j * W[None, :]) ** p[:, None]
    levels = (2e-4, 3e-3, 0.05)
    f_x, zeta, a = 7.3, 0.02, [0.03, -0.02, 0.05]
    e = ExtraMode(7.0, ("c1", "c2", "c3"), tuple(p), levels)
    G = _problem(e, [f_x, zeta] + a, "force", out)
    wx = 2 * np.pi * f_x
    shape = wx**2 / (wx**2 - W**2 + 2j * zeta * wx * W)
    for c in range(3):
        term = a[c] * levels[c] * (1j * W / wx) ** p[c] * shape
        np.testing.assert_allclose(G[c], H[c] + term, rtol=1e-9, atol=1e-15)
    ext = ExtraMode(7.0, ("c1", "c2", "c3"), (0, 0, 0), levels)
    assert ext.names == ("f_x7000", "zeta_x7000", "a_x7000_c1", "a_x7000_c2", "a_x7000_c3")
