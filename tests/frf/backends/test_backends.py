"""FRF backends: the sparse exact FRF against the dense one and the numpy references,
its analytic sensitivities against finite differences, the reduced basis and its
refusal, and general damping in a modal basis recovering its truth."""

import casadi as ca
import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp

from support.cases import write_case
from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.model.damping import (DashpotDamping, GeneralDamping, ModalGeneralDamping, RayleighDamping,
                         rayleigh_from_ratios)
from nlp.errors import InputError
from nlp.frf.reference import frf_dynamic_stiffness, frf_modal, modal_parameters
from nlp.frf.backends import choose
from nlp.frf.backends.dense import frf_symbolic
from nlp.model.nominal import StructuralModel, shear_frame
from nlp.model.parameters import Parameter, ParameterSet
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem


def random_model(n, rng, sparse=True):
    """A chain of n masses with springs to the ground and between random non-adjacent DOFs.

    Influence matrices: one per spring group (chain springs in 3 groups, couplings in one)
    and one per mass; all matrices scipy.sparse when ``sparse``.
    """
    m = rng.uniform(1.0, 3.0, n)
    springs = [(i - 1, i, rng.uniform(500, 1500)) for i in range(n)]  # i - 1 = -1: ground
    springs += [(i, j, rng.uniform(50, 150)) for i, j in rng.integers(0, n, (max(n // 5, 1), 2))
                if abs(i - j) > 1]

    def spring(i, j, k):
        A = np.zeros((n, n))
        if i >= 0:
            A[i, i] += k
            A[i, j] -= k
            A[j, i] -= k
        A[j, j] += k
        return A

    groups = [np.zeros((n, n)) for _ in range(4)]
    for s, (i, j, k) in enumerate(springs):
        groups[min(s * 3 // n, 2) if s < n else 3] += spring(i, j, k)
    wrap = sp.csc_matrix if sparse else np.asarray
    M_infl = tuple(wrap(np.diag(m[r] * np.eye(n)[r])) for r in range(n))
    return StructuralModel(M0=wrap(np.diag(m)), K0=wrap(sum(groups)),
                           M_infl=M_infl, K_infl=tuple(wrap(g) for g in groups),
                           beta_names=tuple(f"m{r + 1}" for r in range(n)),
                           alpha_names=("k_a", "k_b", "k_c", "k_x"),
                           beta_nominal=m, alpha_nominal=np.ones(4))


def param_set(model, damping, fixed_masses=()):
    ps = [Parameter(nm, "stiffness", 0.0, -0.5, 1.0) for nm in model.alpha_names]
    ps += [Parameter(nm, "mass", 0.0, -0.5, 1.0, fixed=i in fixed_masses)
           for i, nm in enumerate(model.beta_names)]
    lo, hi = damping.default_bounds()
    ps += [Parameter(nm, "damping", float(v), float(a), float(b))
           for nm, v, a, b in zip(damping.names, damping.initial(), lo, hi)]
    return ParameterSet(tuple(ps), len(model.alpha_names), len(model.beta_names))


def nonproportional_damping(model, rng, modes=(1, 2, 3)):
    """Modal-basis general damping with modal coupling (C is not proportional)."""
    M0, K0 = model.M0, model.K0
    a0, a1 = rayleigh_from_ratios(M0.toarray(), K0.toarray(), 0.02) if sp.issparse(M0) else \
        rayleigh_from_ratios(M0, K0, 0.02)
    return ModalGeneralDamping.from_model(M0, K0, list(modes), [0.02, 0.03, 0.025][:len(modes)],
                                          a0, a1)


def target(model, omega, dofs, excitation="ground", outputs=None):
    outputs = outputs or ["receptance", "absolute_accelerance", "mobility", "accelerance"]
    if excitation == "force":
        outputs = [o if o != "absolute_accelerance" else "accelerance" for o in outputs]
    chans = tuple(Channel(f"c{i}", d, outputs[i % len(outputs)]) for i, d in enumerate(dofs))
    N = omega.size
    return Target(omega=omega, H=np.ones((len(chans), N)) * (1 + 1j), weight=np.ones((len(chans), N)),
                  channels=chans, excitation=excitation, force_dof=0 if excitation == "force" else None)


def band(model, count=3, points=6):
    K = model.K0.toarray() if sp.issparse(model.K0) else model.K0
    M = model.M0.toarray() if sp.issparse(model.M0) else model.M0
    wn = np.sqrt(sla.eigh(K, M, eigvals_only=True, subset_by_index=[0, count - 1]))
    return np.concatenate([np.linspace(x * 0.97, x * 1.03, points) for x in wn])


@pytest.mark.parametrize("n", [10, 60, 200])
def test_sparse_frf_equals_numpy_references(n):
    """Non-proportional damping (coupled modal basis + dashpots): sparse FRF = direct solve = modal sum."""
    rng = np.random.default_rng(n)
    model = random_model(n, rng)
    damping = nonproportional_damping(model, rng)
    params = param_set(model, damping)
    omega = band(model)
    for excitation in ("ground", "force"):
        tg = target(model, omega, [0, n // 2, n - 1], excitation)
        pr = UpdatingProblem(model, damping, params, tg, frf_backend="sparse")
        z = params.z0 + rng.uniform(-0.1, 0.1, params.n_z)
        H = pr.channel_frfs(z, omega)
        M, K, C = pr.matrices(z)
        assert not np.allclose(C, damping.a0 * M + damping.a1 * K)  # really non-proportional
        for reference in (frf_dynamic_stiffness, frf_modal) if n <= 60 else (frf_dynamic_stiffness,):
            rows = [reference(M, C, K, omega, excitation, 0, ch.output)[ch.dof] for ch in tg.channels]
            ref = np.array(rows)
            assert np.max(np.abs(H - ref) / np.abs(ref)) < 1e-8


def test_sparse_equals_dense_backend_residuals_and_jacobian():
    """Same r and J as the dense symbolic backend (CasADi AD), every residual, three damping models."""
    rng = np.random.default_rng(1)
    n = 10
    model = random_model(n, rng, sparse=False)
    a0, a1 = rayleigh_from_ratios(model.M0, model.K0, 0.02)
    C0 = a0 * model.M0 + a1 * model.K0 + np.diag(rng.uniform(0, 2, n))
    for damping, residuals in (
            (GeneralDamping(C0), ("log_magnitude", "magnitude", "complex")),
            (nonproportional_damping(model, rng), ("complex",)),
            (DashpotDamping(a0, a1, model.K_infl, model.alpha_names), ("log_magnitude",))):
        params = param_set(model, damping, fixed_masses=(0,))
        omega = band(model, points=4)
        for residual in residuals:
            tg = target(model, omega, [1, 6, 9])
            args = (model, damping, params, tg, residual, SolverConfig(compile=False))
            dense = UpdatingProblem(*args, frf_backend="dense")
            sparse = UpdatingProblem(*args, frf_backend="sparse")
            z = params.z0 + rng.uniform(-0.05, 0.05, params.n_z)
            r1, J1 = dense.residuals(z)
            r2, J2 = sparse.residuals(z)
            assert np.max(np.abs(r1 - r2)) < 1e-8 * max(1, np.abs(r1).max())
            assert np.max(np.abs(J1 - J2)) < 1e-8 * np.abs(J1).max()


def test_dense_symbolic_matches_numpy_for_random_damping():
    rng = np.random.default_rng(3)
    n = 10
    M = np.diag(rng.uniform(1, 2, n))
    A = rng.normal(size=(n, n))
    K = A @ A.T + n * np.eye(n)
    B = rng.normal(size=(n, n))
    C = 0.05 * (B @ B.T) + 0.01 * np.eye(n)
    w = 1.3
    b = -M @ np.ones(n)
    hr, hi = frf_symbolic(ca.SX(M), ca.SX(C), ca.SX(K), w, ca.SX(b))
    H = np.array(ca.evalf(hr)).ravel() + 1j * np.array(ca.evalf(hi)).ravel()
    ref = frf_dynamic_stiffness(M, C, K, [w])[:, 0]
    assert np.max(np.abs(H - ref) / np.abs(ref)) < 1e-10


@pytest.mark.parametrize("n", [12, 120])
def test_sparse_sensitivities_equal_finite_differences(n):
    rng = np.random.default_rng(10 + n)
    model = random_model(n, rng)
    for damping in (nonproportional_damping(model, rng),
                    DashpotDamping(0.3, 1e-3, model.K_infl, model.alpha_names)):
        params = param_set(model, damping, fixed_masses=range(3, n))
        omega = band(model, points=4)
        for residual in ("log_magnitude", "complex"):
            tg = target(model, omega, [0, n // 3, n - 1])
            pr = UpdatingProblem(model, damping, params, tg, residual=residual, frf_backend="sparse")
            z = params.z0 + rng.uniform(-0.05, 0.05, params.n_z)
            _, J = pr.residuals(z)
            h = 1e-6
            fd = np.column_stack([(pr.residuals(z + h * e)[0] - pr.residuals(z - h * e)[0]) / (2 * h)
                                  for e in np.eye(params.n_z)])
            assert np.max(np.abs(J - fd)) < 1e-5 * np.abs(fd).max()


def test_batched_banded_and_superlu_paths_agree(monkeypatch):
    """Batched solves (small systems: one eigendecomposition, or one dense LU per frequency,
    all frequencies at once or in blocks), banded LU (narrow band after RCM) and SuperLU give
    the same r and J, with Rayleigh (no border) and modal-basis damping (bordered system)."""
    from nlp.frf.backends import sparse as sparse_backend
    from nlp.frf.backends.pencil import decompose
    rng = np.random.default_rng(5)
    model = random_model(20, rng)
    for damping in (RayleighDamping(0.2, 1e-3), nonproportional_damping(model, rng)):
        params = param_set(model, damping, fixed_masses=range(5, 20))
        tg = target(model, band(model), [3, 10, 19])
        problems = [UpdatingProblem(model, damping, params, tg, frf_backend="sparse")]
        routes = []   # the batched path solves by one eigendecomposition (pencil.py) ...
        monkeypatch.setattr(sparse_backend, "decompose",
                            lambda *a: routes.append(decompose(*a)) or routes[-1])
        z = params.z0 + rng.uniform(-0.1, 0.1, params.n_z)
        r0, J0 = problems[0].residuals(z)
        assert routes and routes[-1] is not None
        monkeypatch.setattr(sparse_backend, "decompose", lambda *a: None)   # ... or by LU
        problems.append(UpdatingProblem(model, damping, params, tg, frf_backend="sparse"))
        monkeypatch.setattr(sparse_backend, "BATCH_BYTES", 16 * 40 ** 2 * 3)  # a few per block
        problems.append(UpdatingProblem(model, damping, params, tg, frf_backend="sparse"))
        monkeypatch.setattr(sparse_backend, "BATCH_MAX", 0)
        problems.append(UpdatingProblem(model, damping, params, tg, frf_backend="sparse"))
        monkeypatch.setattr(sparse_backend, "BAND_MAX", -1)
        problems.append(UpdatingProblem(model, damping, params, tg, frf_backend="sparse"))
        monkeypatch.undo()
        ev = [p.evaluator for p in problems]
        assert ev[1].batched and ev[2].batched and not ev[3].batched and not ev[4].batched
        assert not ev[4].banded and ev[3].banded == (damping.U is None)
        for p in problems[1:]:
            r, J = p.residuals(z)
            assert np.max(np.abs(r - r0)) < 1e-10 and np.max(np.abs(J - J0)) < 1e-9 * np.abs(J0).max()


def test_auto_backend_choice():
    assert choose("auto", 4) == "dense"
    assert choose("auto", 200) == "sparse"
    assert choose("reduced", 200) == "reduced"
    assert choose("sparse", 200, enrichments=("x",)) == "dense"


def test_modal_general_damping_recovers_truth_modal_damping():
    """Simulated FRFs (numpy reference, 1 % noise) of a frame whose band modes are coupled by
    damping; the modal-basis general model recovers the truth modal damping ratios within 10 %."""
    rng = np.random.default_rng(7)
    n = 8
    masses = np.full(n, 2.0)
    k = np.linspace(1800, 1000, n)
    model = shear_frame(masses, k)
    a0, a1 = rayleigh_from_ratios(model.M0, model.K0, 0.02)
    truth_d = ModalGeneralDamping.from_model(model.M0, model.K0, [1, 2, 3], [0.02, 0.04, 0.03],
                                             a0, a1)
    theta_true = np.concatenate([[0.0, 0.0, 0.0], [0.5, -0.3, 0.4]])  # coupling L[2,1], L[3,1], L[3,2]
    alpha_true = rng.uniform(-0.1, 0.1, n)
    M, K = model.matrices(alpha_true, np.zeros(n))
    C = truth_d.matrix(theta_true, M, K)
    f_true, z_true, _ = modal_parameters(M, C, K)
    wn = 2 * np.pi * f_true[:3]
    omega = np.concatenate([np.linspace(x * 0.9, x * 1.1, 15) for x in wn])
    dofs = [1, 4, 7]
    H = frf_dynamic_stiffness(M, C, K, omega)[dofs]
    H = H * np.exp(rng.normal(0, 0.01, H.shape) + 1j * rng.normal(0, 0.01, H.shape))
    damping = ModalGeneralDamping.from_model(model.M0, model.K0, [1, 2, 3], [0.03] * 3, a0, a1)
    params = param_set(model, damping, fixed_masses=tuple(range(n)))
    chans = tuple(Channel(f"c{d}", d) for d in dofs)
    tg = Target(omega=omega, H=H, weight=np.ones(H.shape), channels=chans)
    pr = UpdatingProblem(model, damping, params, tg, residual="complex", frf_backend="sparse")
    res = pr.solve()
    assert res.success
    Mu, Ku, Cu = pr.matrices(res.z)
    f_up, z_up, _ = modal_parameters(Mu, Cu, Ku)
    assert np.all(np.abs(z_up[:3] / z_true[:3] - 1) < 0.10)
    assert np.all(np.abs(f_up[:3] / f_true[:3] - 1) < 0.01)


def test_reduced_backend_reports_error_and_refuses_beyond_noise(tmp_path):
    # 2 % noise: the basis error is far below it, the reduced backend runs and reports it
    path, _ = write_case(str(tmp_path / "noisy"), noise=0.02, model={"frf_backend": "reduced"},
                         damping={"model": "rayleigh"})
    case = assemble(load_case(path))
    pr = build_problem(case)
    assert pr.backend == "reduced" and pr.reduced_info["rms_log_error"] < pr.reduced_info["noise"]
    assert "basis vectors" in pr.describe()
    exact = UpdatingProblem(case.model, case.damping, case.params, case.target, frf_backend="sparse")
    z = case.params.z0
    assert np.allclose(pr.objective(z), exact.objective(z), rtol=1e-3)
    # a basis that leaves out modes in the band misses the FRF: refused with the key named
    from nlp.frf.backends import reduced
    orig = reduced.basis
    try:
        reduced.basis = lambda system, omega_max, **kw: orig(system, omega_max, cutoff=0.05,
                                                             min_modes=1)[:, :2]
        with pytest.raises(InputError) as err:
            build_problem(case)
        assert "model.frf_backend" in str(err.value) and "noise" in str(err.value)
    finally:
        reduced.basis = orig


def test_case_backend_key_gives_the_same_update(tmp_path):
    """model.frf_backend: sparse and dense solve the four-story case to the same point."""
    path, truth = write_case(str(tmp_path / "c"), noise=0.02, damping={"model": "rayleigh"})
    results = {}
    for backend in ("dense", "sparse"):
        cfg = load_case(path)
        cfg = cfg.__class__(**{**cfg.__dict__, "model": cfg.model.__class__(
            **{**cfg.model.__dict__, "frf_backend": backend})})
        case = assemble(cfg)
        pr = build_problem(case)
        assert pr.backend == backend
        res = pr.solve()
        assert res.success
        results[backend] = pr.theta(res.z)
    assert np.allclose(results["dense"], results["sparse"], rtol=1e-4, atol=1e-5)
    k = np.asarray(truth["stiffnesses"])
    sa = slice(0, 4)
    assert np.max(np.abs(np.array([1019, 1217, 1420, 2473]) * (1 + results["sparse"][sa]) / k - 1)) < 0.02
