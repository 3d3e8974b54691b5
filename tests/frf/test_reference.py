"""FRF: state-space solve = modal sum = dynamic stiffness; CasADi FRF = numpy."""

import casadi as ca
import numpy as np
import pytest

from support.frames import random_system
from nlp.frf.reference import (OUTPUTS, frf_dynamic_stiffness, frf_modal, frf_state_space,
                     modal_parameters, complex_modes, state_space_matrices)
from nlp.frf.backends.dense import frf_symbolic


def _cases():
    for excitation in ("ground", "force"):
        for output in OUTPUTS:
            if output == "absolute_accelerance" and excitation == "force":
                continue
            yield excitation, output


@pytest.mark.parametrize("excitation,output", list(_cases()))
@pytest.mark.parametrize("n", [1, 3, 6])
def test_three_evaluations_agree(n, excitation, output, rng):
    M, C, K = random_system(n, rng)
    lam = np.linalg.eigvals(np.linalg.solve(M, K)).real
    omega = np.sort(np.concatenate([np.sqrt(lam), np.linspace(0.05, 2, 7) * np.sqrt(lam.max())]))
    kw = dict(excitation=excitation, force_dof=n - 1, output=output)
    H_ss = frf_state_space(M, C, K, omega, **kw)
    H_ms = frf_modal(M, C, K, omega, **kw)
    H_ds = frf_dynamic_stiffness(M, C, K, omega, **kw)
    scale = np.abs(H_ds).max()
    assert np.abs(H_ss - H_ds).max() / scale < 1e-8
    assert np.abs(H_ms - H_ds).max() / scale < 1e-8


def test_sdof_closed_form():
    m, c, k = 2.0, 0.3, 800.0
    w = np.array([5.0, 19.0, 40.0])
    H = frf_modal(np.array([[m]]), np.array([[c]]), np.array([[k]]), w,
                  excitation="force", force_dof=0)[0]
    np.testing.assert_allclose(H, 1 / (k - w**2 * m + 1j * w * c), rtol=1e-12)
    # ground input: relative displacement per ground acceleration is -m H
    Hg = frf_modal(np.array([[m]]), np.array([[c]]), np.array([[k]]), w)[0]
    np.testing.assert_allclose(Hg, -m / (k - w**2 * m + 1j * w * c), rtol=1e-12)
    Ha = frf_modal(np.array([[m]]), np.array([[c]]), np.array([[k]]), w,
                   output="absolute_accelerance")[0]
    # absolute acceleration transmissibility (k + jwc) / (k - w^2 m + jwc)
    np.testing.assert_allclose(Ha, (k + 1j * w * c) / (k - w**2 * m + 1j * w * c), rtol=1e-12)


def test_eigenvectors_are_A_normalised(rng):
    M, C, K = random_system(4, rng)
    s, Psi = complex_modes(M, C, K)
    A, B = state_space_matrices(M, C, K)
    np.testing.assert_allclose(Psi.T @ A @ Psi, np.eye(8), atol=1e-9)
    np.testing.assert_allclose(Psi.T @ B @ Psi, -np.diag(s), atol=1e-6 * np.abs(s).max())


def test_modal_parameters_sdof():
    m, k, zeta = 3.0, 1200.0, 0.05
    wn = np.sqrt(k / m)
    f, z, _ = modal_parameters(np.array([[m]]), np.array([[2 * zeta * m * wn]]), np.array([[k]]))
    np.testing.assert_allclose(f, wn / (2 * np.pi), rtol=1e-12)
    np.testing.assert_allclose(z, zeta, rtol=1e-12)


@pytest.mark.parametrize("excitation,output", list(_cases()))
def test_casadi_frf_matches_numpy(excitation, output, rng):
    n = 4
    M, C, K = random_system(n, rng)
    w = ca.SX.sym("w")
    b = -M @ np.ones(n) if excitation == "ground" else np.eye(n)[1]
    hr, hi = frf_symbolic(ca.SX(M), ca.SX(C), ca.SX(K), w, ca.SX(b), output)
    fn = ca.Function("h", [w], [hr, hi])
    omega = np.linspace(0.5, 30, 25)
    H_ref = frf_dynamic_stiffness(M, C, K, omega, excitation, 1, output)
    out = [fn(wk) for wk in omega]
    H = np.array([hr.full().ravel() + 1j * hi.full().ravel() for hr, hi in out]).T
    np.testing.assert_allclose(H, H_ref, rtol=1e-9, atol=1e-12 * np.abs(H_ref).max())


@pytest.mark.parametrize("proportional", [True, False])
def test_large_model_routes_equal_a_dense_direct_solve(proportional, rng):
    """Above LARGE_N DOFs: Rayleigh damping goes by the all-mode sum, other damping by one sparse
    LU per frequency; both equal numpy's dense solve of (K - w^2 M + jwC) q = b to 1e-8."""
    import scipy.sparse as sp
    from nlp.frf import reference as frf_mod
    n = frf_mod.LARGE_N + 50
    k = rng.uniform(5e5, 1.5e6, n)
    K = sp.diags([k + np.append(k[1:], 0), -k[1:], -k[1:]], [0, 1, -1]).toarray()
    K[0, n - 1] = K[n - 1, 0] = -1e4  # a non-banded coupling
    K[0, 0] += 1e4
    K[n - 1, n - 1] += 1e4
    M = np.diag(rng.uniform(80, 120, n))
    C = 0.3 * M + 2e-4 * K
    if not proportional:
        C[3, 3] += 50.0
    assert (frf_mod._rayleigh_coefficients(M, C, K) is not None) == proportional
    omega = np.array([10.0, 35.0, 80.0])
    H = frf_dynamic_stiffness(M, C, K, omega, "force", n - 1, "accelerance")
    b = np.zeros(n)
    b[n - 1] = 1
    ref = np.array([-(w ** 2) * np.linalg.solve(K - w ** 2 * M + 1j * w * C, b) for w in omega]).T
    assert np.max(np.abs(H - ref)) < 1e-8 * np.abs(ref).max()
    rows = [n - 1, 7, 0]   # a subset of the DOFs, in the order asked
    Hs = frf_dynamic_stiffness(M, C, K, omega, "force", n - 1, "accelerance", dofs=rows)
    assert Hs.shape == (3, omega.size)
    assert np.max(np.abs(Hs - ref[rows])) < 1e-8 * np.abs(ref).max()
