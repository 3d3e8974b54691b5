"""The sparse backend's fast paths: the batched banded LDL^T over all frequencies against an
independent modal sum, its Jacobian against central differences and against the other
linear-solver paths, the growth check's bound on every solve's residual, and the pivoted
fallback when the check fails."""

import numpy as np
import pytest
import scipy.sparse as sp

from nlp.frf.backends import banded, sparse as sparse_backend
from nlp.model.damping import RayleighDamping
from nlp.model.nominal import shear_frame
from nlp.model.parameters import Parameter, ParameterSet
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem
from nlp.testing.tall import modal_receptance, tall_frame


def tall_problem(n, residual="log_magnitude", every=1):
    """The tall frame's truth as the model (per-storey k and m free, floor-1 mass fixed,
    Rayleigh a0, a1 free), its data on every ``every``-th frequency."""
    fr = tall_frame(n, seed=0)
    model = shear_frame(fr.m, fr.k, sparse=True)
    damping = RayleighDamping(fr.a0, fr.a1)
    ps = [Parameter(nm, "stiffness", 0.0, -0.5, 1.0) for nm in model.alpha_names]
    ps += [Parameter(nm, "mass", 0.0, -0.5, 1.0, fixed=i == 0) for i, nm in enumerate(model.beta_names)]
    ps += [Parameter(nm, "damping", float(v), 0.01, 100.0) for nm, v in zip(damping.names, damping.initial())]
    params = ParameterSet(tuple(ps), n, n)
    omega = 2 * np.pi * fr.f[::every]
    chans = tuple(Channel(f"floor{d + 1}", d, "receptance") for d in fr.dofs)
    tg = Target(omega=omega, H=fr.H[:, ::every], weight=np.ones((len(chans), omega.size)),
                channels=chans, excitation="ground")
    pr = UpdatingProblem(model, damping, params, tg, residual=residual, frf_backend="sparse",
                         solver=SolverConfig(compile=False))
    return fr, pr, omega


def test_batched_banded_frf_equals_modal_sum():
    """64 storeys, 2,560 frequencies from 0.5 f1 to 1.1 f64: the batched banded path gives the
    modal-sum receptances of the truth to 1e-9, with no fallback."""
    fr, pr, omega = tall_problem(64)
    ev = pr.evaluator
    assert ev.banded and ev.bw == 1 and not ev.batched
    H = pr.channel_frfs(pr.params.z0, omega)
    ref, _ = modal_receptance(fr.m, fr.k, omega, fr.dofs, fr.a0, fr.a1)
    assert np.max(np.abs(H - ref) / np.abs(ref)) < 1e-9
    assert ev.fallbacks == 0


@pytest.mark.parametrize("residual", ["log_magnitude", "complex"])
def test_batched_banded_jacobian_equals_central_differences(residual):
    """Stiffness, mass and both Rayleigh columns of J against central differences of r."""
    _, pr, _ = tall_problem(32, residual, every=4)
    rng = np.random.default_rng(2)
    z = pr.params.z0 + rng.uniform(-0.05, 0.05, pr.params.n_z)
    _, J = pr.residuals(z)
    n_z = pr.params.n_z
    for j in (0, 17, 31, 32, 50, n_z - 2, n_z - 1):
        h = 1e-6 * max(1.0, abs(z[j]))
        e = np.zeros(n_z)
        e[j] = h
        fd = (pr.residuals(z + e)[0] - pr.residuals(z - e)[0]) / (2 * h)
        assert np.max(np.abs(J[:, j] - fd)) < 1e-6 * np.abs(fd).max(), j


def test_banded_superlu_and_dense_paths_agree_on_tall_frame(monkeypatch):
    """r and J by the batched banded LDL^T = by SuperLU (RCM, per frequency) = by the batched
    dense LU, to 1e-9 of each column's largest entry."""
    _, pr0, _ = tall_problem(32, every=8)
    z = pr0.params.z0 + np.random.default_rng(3).uniform(-0.1, 0.1, pr0.params.n_z)
    r0, J0 = pr0.residuals(z)
    monkeypatch.setattr(sparse_backend, "BAND_MAX", -1)
    _, pr1, _ = tall_problem(32, every=8)
    monkeypatch.setattr(sparse_backend, "BATCH_MAX", 1000)
    _, pr2, _ = tall_problem(32, every=8)
    assert pr0.evaluator.banded and not pr1.evaluator.banded and pr2.evaluator.batched
    for pr in (pr1, pr2):
        r, J = pr.residuals(z)
        assert np.max(np.abs(r - r0)) < 1e-9 * np.abs(r0).max()
        assert np.max(np.abs(J - J0) / np.abs(J0).max(axis=0)) < 1e-9


def test_forced_fallback_gives_the_pivoted_answer(monkeypatch):
    """A near-zero first pivot forced into every third frequency's unpivoted factorisation: the
    growth check flags exactly those, LAPACK's pivoted solver re-solves them from the true Z,
    and r and J are those of the unforced run."""
    _, pr, _ = tall_problem(32, every=8)
    z = pr.params.z0 + 0.05
    r0, J0 = pr.residuals(z)
    factor = banded.ldlt_banded

    def near_zero_pivot(L):
        L[0, 0, ::3] = 1e-300
        return factor(L)

    monkeypatch.setattr(banded, "ldlt_banded", near_zero_pivot)
    _, pr, _ = tall_problem(32, every=8)
    r, J = pr.residuals(z)
    assert pr.evaluator.fallbacks == len(range(0, pr.target.omega.size, 3))
    assert np.max(np.abs(r - r0)) < 1e-9 * np.abs(r0).max()
    assert np.max(np.abs(J - J0) / np.abs(J0).max(axis=0)) < 1e-9


def random_band(rng, n, b, N, zero_pivot_at=None):
    """Complex symmetric banded Z_k = K - w^2 M + jw C (K, M, C banded SPD) at N frequencies."""
    def spd():
        A = sp.diags([rng.uniform(0.5, 1.0, n - p) for p in range(b + 1)], list(range(b + 1)))
        return (A @ A.T).toarray()
    K, M, C = spd(), spd(), 0.01 * spd()
    w = np.linspace(0.1, 3.0, N)
    Z = K[None] - w[:, None, None] ** 2 * M[None] + 1j * w[:, None, None] * C[None]
    if zero_pivot_at is not None:
        Z[zero_pivot_at, 0, 0] = 0.0                  # nonsingular, but no pivot-free LDL^T
    L = np.zeros((b + 1, n, N), complex)
    for p in range(b + 1):
        L[p, :n - p] = np.diagonal(Z, -p, axis1=1, axis2=2).T
    return Z, L


@pytest.mark.parametrize("b", [1, 3])
def test_growth_bounds_every_residual_and_flags_a_zero_pivot(b):
    """||Z x - b|| <= gamma G ||Z|| ||x|| (Higham Thm 9.4) holds for every right-hand side;
    a zero leading pivot is flagged and that frequency solved exactly by the fallback."""
    rng = np.random.default_rng(b)
    n, N = 30, 40
    Z, L = random_band(rng, n, b, N, zero_pivot_at=7)
    rhs = rng.normal(size=(n, 3))
    X, bad = banded.solve_banded_batch(L.copy(), rhs)
    assert list(bad) == [7]
    with np.errstate(all="ignore"):
        G = banded.growth(banded.ldlt_banded(L.copy()), banded.row_norm(L))
    gamma = 3 * (b + 1) * np.finfo(float).eps * 4   # complex arithmetic: a few real roundings
    for k in range(N):
        R = Z[k] @ X[:, :, k] - rhs
        if k == 7:
            X7 = banded.solve_pivoted(L[:, :, k], rhs)
            assert np.max(np.abs(Z[k] @ X7 - rhs)) < 1e-12 * np.abs(Z[k]).sum(1).max() * np.abs(X7).max()
            continue
        bound = gamma * G[k] * np.abs(Z[k]).sum(axis=1).max() * np.abs(X[:, :, k]).max(axis=0)
        assert np.all(np.abs(R).max(axis=0) <= bound)
        ref = np.linalg.solve(Z[k], rhs)
        assert np.max(np.abs(X[:, :, k] - ref)) < 1e-10 * np.abs(ref).max()


def test_frf_sensitivities_equal_central_differences():
    """SparseFRF.frf(z, w, jacobian=True): complex dH/dz against central differences of H."""
    _, pr, omega = tall_problem(32, every=16)
    ev = pr.evaluator
    z = pr.params.z0 + np.random.default_rng(4).uniform(-0.05, 0.05, pr.params.n_z)
    H, dH = ev.frf(z, omega, jacobian=True)
    assert np.array_equal(H, ev.frf(z, omega))
    for j in (3, 40, pr.params.n_z - 1):
        e = np.zeros(pr.params.n_z)
        e[j] = 1e-6
        fd = (ev.frf(z + e, omega) - ev.frf(z - e, omega)) / 2e-6
        assert np.max(np.abs(dH[j] - fd)) < 1e-6 * np.abs(fd).max(), j


def test_band_is_the_lower_band_of_the_dynamic_stiffness():
    """SparseFRF's band at z equals K - w^2 M + jw C of the model's own matrices (C Rayleigh,
    Eqns 2-5) in the RCM order, entry by entry, to 1e-14."""
    _, pr, omega = tall_problem(32, every=40)
    ev = pr.evaluator
    assert ev.banded
    z = pr.params.z0 + np.random.default_rng(5).uniform(-0.1, 0.1, pr.params.n_z)
    M, K, C = pr.matrices(z)
    st = ev._state(z)
    L = ev._band(st, omega)
    p = ev.perm
    for k, w in enumerate(omega):
        Z = (K - w ** 2 * M + 1j * w * C)[np.ix_(p, p)]
        for q in range(ev.bw + 1):
            ref = np.diagonal(Z, -q)
            assert np.max(np.abs(L[q, :ev.n - q, k] - ref)) <= 1e-14 * np.abs(Z).max()


def test_tridiagonal_factors_rebuild_z():
    """b = 1: the factors of ldlt_banded give back Z = L D L^T at every frequency (1e-13)."""
    rng = np.random.default_rng(6)
    n, N = 25, 12
    Z, L = random_band(rng, n, 1, N)
    F = banded.ldlt_banded(L.copy())
    for k in range(N):
        Lk = np.eye(n, dtype=complex) + np.diag(F[1, :n - 1, k], -1)
        rebuilt = Lk @ np.diag(1.0 / F[0, :, k]) @ Lk.T
        assert np.max(np.abs(rebuilt - Z[k])) < 1e-13 * np.abs(Z[k]).max()


def test_jacobian_in_place_equals_normal_equations():
    """J summed in place into its column-major store (residuals) gives the J^T r and J^T J
    that normal_equations sums chunk by chunk from its own blocks, over several chunks."""
    _, pr, _ = tall_problem(32)
    ev = pr.evaluator
    data = pr._data(pr._p)
    assert len(ev._chunks(data[0].size, pr.n_res)) > 1
    z = pr.params.z0 + np.random.default_rng(7).uniform(-0.05, 0.05, pr.params.n_z)
    r, J = ev.residuals(z, data)
    r2, g, A = ev.normal_equations(z, data)
    assert np.array_equal(r, r2)
    assert np.max(np.abs(J.T @ r - g)) < 1e-10 * np.abs(g).max()
    assert np.max(np.abs(J.T @ J - A)) < 1e-10 * np.abs(A).max()
