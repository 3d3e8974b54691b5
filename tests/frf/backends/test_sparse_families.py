"""Added physics on the sparse backend (nlp.frf.backends.terms): its FRF and Jacobian equal
the dense backend's, its Jacobian a finite difference, and an appendage's own DOF an
independent numpy solve of the augmented M, C, K."""

import math

import numpy as np
import pytest

from nlp.diagnosis.families import (AddedMass, BaseFlexibility, ExtraMode, HystereticDamping,
                                    LocalDamper,
                                    NonadjacentCoupling, SecondaryOscillator, SensorDelay,
                                    SensorGain, extend_parameters)
from nlp.diagnosis.nuisance import hold
from nlp.frf.backends import choose
from nlp.model.damping import RayleighDamping
from nlp.model.nominal import shear_frame, shear_stiffness
from nlp.model.parameters import Parameter, ParameterSet
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem

m = np.array([3.0, 2.5, 2.0, 1.5])
k = np.array([3000.0, 2500.0, 2000.0, 1800.0])
A0, A1 = 0.3, 0.001
REF = {"m_ref": 2.5, "k_ref": 2500.0, "c_ref": 2.0}
W = np.linspace(3.0, 80.0, 30)
OUTPUTS = ("receptance", "absolute_accelerance", "mobility", "accelerance")

CASES = {
    "added_mass": ([AddedMass(2)], [[0.4]]),
    "appendage": ([SecondaryOscillator(3, 6.0)], [[0.05, 5.5, 0.03]]),
    "damper_ground": ([LocalDamper(1, 0)], [[1.5]]),
    "damper": ([LocalDamper(4, 2)], [[2.0]]),
    "hysteretic": ([HystereticDamping()], [[0.03]]),
    "hysteretic_story": ([HystereticDamping(2)], [[0.05]]),
    "coupling": ([NonadjacentCoupling(1, 3)], [[300.0]]),
    "gain": ([SensorGain("c2")], [[0.1]]),
    "delay": ([SensorDelay("c3")], [[4.0]]),
    "extra_mode": ([ExtraMode(9.0, ("c1", "c4"), (0, 2), (0.01, 2.0))],
                   [[9.1, 0.02, 0.3, -0.2]]),
    "base": ([BaseFlexibility()], [[1.0, math.log10(2500.0) + 0.5, 3.0]]),
    # an appendage and a loss before the base (both re-routed through it), a mass after it
    "several_base": ([SecondaryOscillator(2, 4.0), HystereticDamping(), BaseFlexibility(),
                      AddedMass(4), NonadjacentCoupling(1, 3)],
                     [[0.03, 4.4, 0.05], [0.02], [2.0, math.log10(2500.0) + 1.0, 5.0], [0.3],
                      [150.0]]),
    # parameters held at their reference (nlp.diagnosis.nuisance): constants of the terms
    "held_appendage": ([hold(SecondaryOscillator(3, 6.0), ["zeta_s3"], REF)], [[0.05, 5.5]]),
    "held_base": ([hold(BaseFlexibility(), ["m_base", "c_base"], REF)],
                  [[math.log10(2500.0) + 0.5]]),
    "several": ([ExtraMode(9.0, ("c1", "c2"), (0, 2), (0.01, 2.0)), NonadjacentCoupling(2, 4),
                 SecondaryOscillator(2, 4.0), HystereticDamping(), AddedMass(4), SensorGain("c1"),
                 SensorDelay("c1")],
                [[9.1, 0.02, 0.3, -0.2], [-200.0], [0.03, 4.4, 0.05], [0.02], [0.3], [-0.05],
                 [2.0]]),
}


def _params(damping):
    n = m.size
    ps = [Parameter(f"k{i + 1}", "stiffness", 0.0, -0.5, 1.0, nominal=k[i]) for i in range(n)]
    ps += [Parameter(f"m{i + 1}", "mass", 0.0, -0.5, 1.0, nominal=m[i]) for i in range(n)]
    lo, hi = damping.default_bounds()
    ps += [Parameter(nm, "damping", t, a, b) for nm, t, a, b in
           zip(damping.names, damping.initial(), lo, hi)]
    return ParameterSet(tuple(ps), n, n)


def _problem(fams, values, backend, excitation="ground", residual="log_magnitude"):
    damping = RayleighDamping(A0, A1)
    params = extend_parameters(_params(damping), fams, REF, values)
    outs = [o if excitation == "ground" or o != "absolute_accelerance" else "accelerance"
            for o in OUTPUTS]
    chans = tuple(Channel(f"c{i + 1}", i, o) for i, o in enumerate(outs))
    rng = np.random.default_rng(1)
    H = (1 + 0.3 * rng.standard_normal((4, W.size))) * np.exp(1j * rng.uniform(0, 6, (4, W.size)))
    tg = Target(W, H, np.ones((4, W.size)), chans, excitation,
                None if excitation == "ground" else 1)
    return UpdatingProblem(shear_frame(m, k), damping, params, tg, residual=residual,
                           solver=SolverConfig(compile=False), enrichments=fams, refs=REF,
                           frf_backend=backend)


def _z(pr):
    """A point off the start, inside the bounds: every parameter moved."""
    lo, hi = (np.asarray(b, float) for b in pr.bounds)
    z0 = np.asarray(pr.z0, float)
    return z0 + 0.1 * np.minimum(hi - z0, 1.0) * np.linspace(0.3, 1.0, z0.size)


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("excitation,residual", [("ground", "log_magnitude"),
                                                 ("force", "complex")])
def test_sparse_equals_dense(name, excitation, residual):
    fams, values = CASES[name]
    dense = _problem(fams, values, "dense", excitation, residual)
    sparse = _problem(fams, values, "sparse", excitation, residual)
    assert sparse.backend == "sparse" and dense.backend == "dense"
    z = _z(dense)
    Hd, Hs = dense.channel_frfs(z, W), sparse.channel_frfs(z, W)
    np.testing.assert_allclose(Hs, Hd, rtol=1e-10, atol=1e-12 * np.abs(Hd).max())
    rd, Jd = dense.residuals(z)
    rs, Js = sparse.residuals(z)
    np.testing.assert_allclose(rs, rd, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(Js, Jd, rtol=1e-8, atol=1e-8 * np.abs(Jd).max())


@pytest.mark.parametrize("name", ["appendage", "hysteretic", "several", "several_base"])
def test_sparse_jacobian_finite_difference(name):
    fams, values = CASES[name]
    pr = _problem(fams, values, "sparse", "ground", "complex")
    z = _z(pr)
    _, J = pr.residuals(z)
    h = 1e-6
    for j in range(z.size):
        e = np.zeros(z.size)
        e[j] = h
        fd = (pr.residuals(z + e)[0] - pr.residuals(z - e)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-6 * max(np.abs(fd).max(), 1))


def test_frf_jacobian_of_gain_and_terms_is_a_finite_difference():
    fams, values = CASES["several"]
    ev = _problem(fams, values, "sparse").evaluator
    z = _z(_problem(fams, values, "sparse"))
    _, dH = ev.frf(z, W, jacobian=True)
    h = 1e-6
    for j in range(z.size):
        e = np.zeros(z.size)
        e[j] = h
        fd = (ev.frf(z + e, W) - ev.frf(z - e, W)) / (2 * h)
        np.testing.assert_allclose(dH[j], fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


def test_appendage_dof_is_the_augmented_solve():
    """The oscillator's own DOF: (K - w^2 M + j w C) q = -M r on the augmented matrices, r = 1
    on every DOF (a rigid ground motion carries the appendage with its floor)."""
    mu, fs, zeta = 0.05, 5.5, 0.03
    pr = _problem([SecondaryOscillator(3, 6.0)], [[mu, fs, zeta]], "sparse")
    z = np.asarray(pr.z0, float)
    ev = pr.evaluator
    st = ev._state(z)
    q, _ = ev._solve(st, W, False)
    ms = mu * REF["m_ref"]
    ws = 2 * math.pi * fs
    ks, cs = ms * ws ** 2, 2 * zeta * ms * ws
    K = shear_stiffness(k)
    C = A0 * np.diag(m) + A1 * K
    v = np.array([0, 0, 1.0, 0, -1.0])
    Ma = np.diag([*m, ms])
    Ka = np.pad(K, (0, 1)) + ks * np.outer(v, v)
    Ca = np.pad(C, (0, 1)) + cs * np.outer(v, v)
    b = -Ma @ np.ones(5)
    ref = np.array([np.linalg.solve(Ka - w ** 2 * Ma + 1j * w * Ca, b) for w in W]).T
    assert q.shape == (5, W.size)
    np.testing.assert_allclose(q, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


def test_appendage_and_mass_are_a_low_rank_update_of_the_modal_sum():
    """16 floors, an appendage and an added mass on a Rayleigh frame: the small dense system
    is solved by the frame's modal sum and a rank-3 Woodbury update (pencil.Updated), not
    the first-order form, and q is the numpy solve of the augmented M, C, K."""
    from nlp.frf.backends.pencil import Updated
    n = 16
    mt, kt = np.linspace(3.0, 1.5, n), np.linspace(3000.0, 1800.0, n)
    mu, fs, zeta, dm = 0.04, 5.0, 0.03, 0.6
    fams = [SecondaryOscillator(9, 6.0), AddedMass(4)]
    damping = RayleighDamping(A0, A1)
    ps = [Parameter(f"k{i + 1}", "stiffness", 0.0, -0.5, 1.0, nominal=kt[i]) for i in range(n)]
    ps += [Parameter(f"m{i + 1}", "mass", 0.0, -0.5, 1.0, nominal=mt[i]) for i in range(n)]
    ps += [Parameter(nm, "damping", t, a, b, fixed=True) for nm, t, a, b in
           zip(damping.names, damping.initial(), *damping.default_bounds())]
    params = extend_parameters(ParameterSet(tuple(ps), n, n), fams, REF, [[mu, fs, zeta], [dm]])
    tg = Target(W, np.ones((1, W.size)), np.ones((1, W.size)),
                (Channel("c1", n - 1, "accelerance"),), "ground", None)
    pr = UpdatingProblem(shear_frame(mt, kt), damping, params, tg, enrichments=fams, refs=REF,
                         solver=SolverConfig(compile=False), frf_backend="sparse")
    ev = pr.evaluator
    st = ev._state(np.asarray(pr.z0, float))
    q, _ = ev._solve(st, W, False)
    assert isinstance(st.pencil, Updated) and st.pencil.Q.shape[1] == 3
    ms, ws = mu * REF["m_ref"], 2 * math.pi * fs
    K = shear_stiffness(kt)
    C = A0 * np.diag(mt) + A1 * K
    v = np.zeros(n + 1)
    v[[8, n]] = 1.0, -1.0
    Ma = np.diag([*mt, ms])
    Ma[3, 3] += dm
    Ka = np.pad(K, (0, 1)) + ms * ws ** 2 * np.outer(v, v)
    Ca = np.pad(C, (0, 1)) + 2 * zeta * ms * ws * np.outer(v, v)
    b = -Ma @ np.ones(n + 1)
    ref = np.array([np.linalg.solve(Ka - w ** 2 * Ma + 1j * w * Ca, b) for w in W]).T
    np.testing.assert_allclose(q, ref, rtol=1e-9, atol=1e-11 * np.abs(ref).max())


def test_choose_keeps_sparse_for_large_models_with_families():
    fams = [AddedMass(1)]
    assert choose("auto", 4, fams) == "dense"
    assert choose("auto", 120, fams) == "sparse"
    assert choose("sparse", 4, fams) == "sparse"
    assert choose("dense", 120, fams) == "dense"
    assert choose("reduced", 120, fams) == "reduced"


def test_flexible_base_is_sparse_only_with_rayleigh_damping_and_no_base_sensor():
    from nlp.model.damping import GeneralDamping
    fams = [BaseFlexibility()]
    ray = RayleighDamping(A0, A1)
    floor = (Channel("a1", 0, "absolute_accelerance"),)
    base = floor + (Channel("a0", -1, "absolute_accelerance"),)
    assert choose("sparse", 120, fams, ray, floor) == "sparse"
    assert choose("sparse", 120, fams, ray, base) == "dense"
    assert choose("sparse", 120, fams, GeneralDamping(np.eye(4)), floor) == "dense"
    assert choose("sparse", 120, fams) == "dense"   # damping unknown


def test_reduced_backend_projects_the_terms():
    """On a complete basis (n vectors: the projection is a change of coordinates) the reduced
    backend's FRF and Jacobian with families equal the sparse backend's."""
    fams, values = CASES["several"]
    sparse = _problem(fams, values, "sparse")
    damping = RayleighDamping(A0, A1)
    Psi = np.linalg.qr(np.random.default_rng(3).standard_normal((4, 4)))[0] * 0.7
    red = UpdatingProblem(shear_frame(m, k), damping, sparse.params, sparse.target,
                          solver=SolverConfig(compile=False), enrichments=fams, refs=REF,
                          frf_backend="reduced", basis=Psi)
    assert red.backend == "reduced"
    z = _z(sparse)
    np.testing.assert_allclose(red.channel_frfs(z, W), sparse.channel_frfs(z, W), rtol=1e-9)
    np.testing.assert_allclose(red.residuals(z)[1], sparse.residuals(z)[1], rtol=1e-7,
                               atol=1e-9 * np.abs(sparse.residuals(z)[1]).max())
    for Ar, As in zip(red.system_matrices(z), sparse.system_matrices(z)):
        np.testing.assert_allclose(Ar, As, rtol=1e-12)


def _tall(n):
    """A shear frame of n floors with families on far-apart floors, and its numpy Z(w), b."""
    mt = np.linspace(2.0, 1.0, n)
    kt = np.linspace(4000.0, 2000.0, n)
    fams = [NonadjacentCoupling(5, n - 3), SecondaryOscillator(n // 2, 5.0), HystereticDamping(3),
            AddedMass(10), LocalDamper(7, 0)]
    values = [[150.0], [0.02, 4.0, 0.04], [0.03], [0.2], [1.0]]
    K = shear_stiffness(kt)
    C = A0 * np.diag(mt) + A1 * K
    ms, ws = 0.02 * REF["m_ref"], 2 * math.pi * 4.0
    N = n + 1
    Ma, Ka, Ca, Kh = (np.pad(A, (0, 1)) for A in (np.diag(mt), K, C, np.zeros((n, n))))
    Ma[9, 9] += 0.2
    Ma[n, n] = ms
    u = np.zeros(N)
    u[[4, n - 4]] = 1, -1
    Ka += 150.0 * np.outer(u, u)
    v = np.zeros(N)
    v[[n // 2 - 1, n]] = 1, -1
    Ka += ms * ws ** 2 * np.outer(v, v)
    Ca += 2 * 0.04 * ms * ws * np.outer(v, v)
    Ca[6, 6] += 1.0
    K3 = shear_stiffness(np.where(np.arange(n) == 2, kt, 0.0))   # story 3 alone
    Kh[:n, :n] += 0.03 * K3
    return mt, kt, fams, values, (Ma, Ka, Ca, Kh)


@pytest.mark.parametrize("band_max", [40, 0])
def test_tall_frame_banded_and_superlu_paths(monkeypatch, band_max):
    """n = 40: the banded L D L^T path (and SuperLU when the band limit is 0) against a numpy
    solve of the augmented system, and their Jacobian against a finite difference."""
    import nlp.frf.backends.sparse as sparse_mod
    monkeypatch.setattr(sparse_mod, "BAND_MAX", band_max)
    n = 40
    mt, kt, fams, values, (Ma, Ka, Ca, Kh) = _tall(n)
    damping = RayleighDamping(A0, A1)
    ps = [Parameter(f"k{i + 1}", "stiffness", 0.0, -0.5, 1.0) for i in range(n)]
    ps += [Parameter(f"m{i + 1}", "mass", 0.0, -0.5, 1.0, fixed=True) for i in range(n)]
    ps += [Parameter(nm, "damping", 1.0, 0.0, 30.0) for nm in damping.names]
    params = extend_parameters(ParameterSet(tuple(ps), n, n), fams, REF, values)
    chans = tuple(Channel(f"c{i}", i, "absolute_accelerance") for i in (0, 19, 39))
    w = np.linspace(3.0, 60.0, 12)
    tg = Target(w, np.ones((3, w.size), complex), np.ones((3, w.size)), chans, "ground", None)
    pr = UpdatingProblem(shear_frame(mt, kt), damping, params, tg, residual="complex",
                         solver=SolverConfig(compile=False), enrichments=fams, refs=REF,
                         frf_backend="sparse")
    ev = pr.evaluator
    assert pr.backend == "sparse" and ev.banded == (band_max > 0) and ev.n == n + 1
    z = np.asarray(pr.z0, float)
    b = -Ma @ np.ones(n + 1)
    q = np.array([np.linalg.solve(Ka - x ** 2 * Ma + 1j * (x * Ca + Kh), b) for x in w]).T
    H = -(w ** 2) * q[[0, 19, 39]] + 1
    np.testing.assert_allclose(ev.frf(z, w), H, rtol=1e-9)
    _, J = pr.residuals(z)
    for j in [0, 2, z.size - 7, z.size - 6, z.size - 5, z.size - 4, z.size - 1]:
        e = np.zeros(z.size)
        e[j] = 1e-4  # the banded solve is good to ~1e-12: a wide step keeps FD noise below 1e-8
        fd = (pr.residuals(z + e)[0] - pr.residuals(z - e)[0]) / 2e-4
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())


def test_massless_appendage_is_no_appendage():
    """At its null value (mass ratio 0) an appendage leaves the FRF of the frame without it
    (the extra DOF's row would vanish: the sparse backend keeps it solvable)."""
    pr = _problem([SecondaryOscillator(3, 6.0)], [[0.0, 5.5, 0.03]], "sparse")
    bare = _problem([], None, "sparse")
    z = np.asarray(pr.z0, float)
    np.testing.assert_allclose(pr.channel_frfs(z, W), bare.channel_frfs(z[:-3], W), rtol=1e-9)


def test_whole_system_matrices_equal_the_dense_backend():
    """M, K, C with the appended DOFs (an appendage's modes are judged on them)."""
    fams, values = CASES["several"]
    dense, sparse = _problem(fams, values, "dense"), _problem(fams, values, "sparse")
    z = _z(dense)
    for Ad, As in zip(dense.system_matrices(z), sparse.system_matrices(z)):
        assert As.shape == (5, 5)
        np.testing.assert_allclose(As, Ad, rtol=1e-12, atol=1e-12 * np.abs(Ad).max())
