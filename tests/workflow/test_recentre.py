"""The re-centred reduced basis (nlp.workflow.recentre) on a mid-size model where the nominal basis is biased.

The reference is independent of the reduced machinery: the exact sparse backend's
optimum on the same data. The data come from a modal-superposition simulator over all
undamped modes (exact for Rayleigh damping), not from the package's FRF code.
"""

import os

import numpy as np
import pytest
import scipy.io
import scipy.linalg as sla
import scipy.sparse as sp
import yaml

from nlp.case.assemble import assemble, build_problem
from nlp.case.load import load_case
from nlp.solve.identify import standard_errors
from nlp.workflow.recentre import recentre

N_DOF, GROUPS = 240, 6
A0, A1 = 0.05, 2e-4   # Rayleigh [1/s], [s]


def chain(k):
    """Stiffness of a fixed-base chain with spring k[i] below mass i."""
    n = k.size
    upper = np.append(k[1:], 0.0)
    return sp.diags([k + upper, -k[1:], -k[1:]], [0, 1, -1], format="csc")


def write_chain_case(folder, backend, noise=0.01, seed=3, **model):
    """A 240-DOF chain as matrix files, 6 stiffness groups changed by up to 12 %, force at
    the top, accelerances at 4 DOFs; returns (case path, true relative changes)."""
    rng = np.random.default_rng(seed)
    n = N_DOF
    m = np.full(n, 100.0)
    k = 4.0e7 * np.linspace(1.5, 1.0, n)
    groups = np.array_split(np.arange(n), GROUPS)
    change = rng.uniform(-0.12, 0.12, GROUPS)
    os.makedirs(os.path.join(folder, "groups"), exist_ok=True)
    scipy.io.mmwrite(os.path.join(folder, "M.mtx"), sp.diags(m, format="csc"))
    scipy.io.mmwrite(os.path.join(folder, "K.mtx"), chain(k))
    k_true = k.copy()
    for i, g in enumerate(groups):
        kg = np.zeros(n)
        kg[g] = k[g]
        sp.save_npz(os.path.join(folder, "groups", f"g{i + 1}.npz"), chain(kg))
        k_true[g] *= 1 + change[i]
    # truth FRF: modal superposition over all modes (Rayleigh: modal damping a0/(2w) + a1 w/2)
    lam, Phi = sla.eigh(chain(k_true).toarray(), np.diag(m))
    wr = np.sqrt(lam)
    band_top = wr[3] * 1.15
    f = np.linspace(0.8 * wr[0], band_top, 240) / (2 * np.pi)
    w = 2 * np.pi * f
    dofs, force = [59, 119, 179, 239], 239
    den = wr[:, None] ** 2 - w[None, :] ** 2 + 1j * w[None, :] * (A0 + A1 * wr[:, None] ** 2)
    H = -(w ** 2) * ((Phi[dofs] * Phi[force]) @ (1.0 / den))
    H = H * np.exp(rng.normal(0, noise, H.shape) + 1j * rng.normal(0, noise, H.shape))
    np.savez(os.path.join(folder, "frf.npz"), f=f, H=H)
    cfg = {"name": "chain240",
           "model": {"type": "matrices", "M": "M.mtx", "K": "K.mtx", "frf_backend": backend,
                     "stiffness_groups": {f"g{i + 1}": f"groups/g{i + 1}.npz"
                                          for i in range(GROUPS)}, **model},
           "parameters": {"stiffness_bounds": [-0.5, 1.0]},
           "damping": {"model": "rayleigh", "a0": A0 * 1.2, "a1": A1 * 0.8},
           "excitation": {"type": "force", "floor": force + 1},
           "data": {"file": "frf.npz", "window": "none", "channels": [
               {"name": f"a{d + 1}", "floor": d + 1, "output": "accelerance", "column": c}
               for c, d in enumerate(dofs)]},
           "frequencies": {"method": "all"},
           "objective": {"residual": "log_magnitude"},
           "search": {"starts": 1, "seed": 0, "workers": 1}}
    path = os.path.join(folder, "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    return path, change


def exact_optimum(folder):
    """(case, local solve, standard errors) of the chain on the exact sparse backend."""
    path, _ = write_chain_case(str(folder), "sparse")
    case = assemble(load_case(path))
    exact = build_problem(case)
    ref = exact.solve()
    r, J = exact.residuals(ref.z)
    return case, ref, np.sqrt(np.diag(standard_errors(J, r, exact.n_used)[0]))


def test_recentred_reduced_fit_equals_exact_sparse_fit(tmp_path):
    """The nominal basis (modes up to 3 x the band's top, static and residual-flexibility
    vectors; ln|H| error < 1e-4 at z0) cannot follow 12 % stiffness changes: its fit is several
    standard errors off. Re-centring the basis on the fit removes the bias: the result agrees
    with the exact sparse backend's optimum within 0.2 standard errors (measured 0.14)."""
    path, change = write_chain_case(str(tmp_path / "exact"), "sparse")
    case = assemble(load_case(path))
    exact = build_problem(case)
    assert exact.backend == "sparse"
    ref = exact.solve()
    assert ref.success
    r, J = exact.residuals(ref.z)
    se = np.sqrt(np.diag(standard_errors(J, r, exact.n_used)[0]))
    na = GROUPS
    assert np.all(np.abs((1 + ref.z[:na]) / (1 + change) - 1) < 5 * se[:na])  # sanity: near truth

    path_r, _ = write_chain_case(str(tmp_path / "reduced"), "reduced", reduced_cutoff=3.0)
    case_r = assemble(load_case(path_r))
    nominal = build_problem(case_r)
    assert nominal.backend == "reduced"
    res0 = nominal.solve()
    bias0 = np.max(np.abs(res0.z - ref.z) / se)
    assert bias0 > 1.0, f"the nominal basis should be biased here (bias {bias0:.2f} SE)"
    logs = []
    problem, best, info = recentre(case_r, nominal, res0, log=logs.append)
    bias = np.max(np.abs(best.z - ref.z) / se)
    assert info["converged"] and len(info["passes"]) <= 4
    assert bias < 0.2, f"re-centred fit {bias:.3f} SE from the exact optimum (nominal {bias0:.2f})"
    final = info["final_check"]
    assert final["rms_log_error"] < final["noise"] and problem.reduced_info["recentred"]
    assert any("reduced vs exact" in m for m in logs)


def test_band_continuation_reaches_the_exact_optimum_and_validates_its_key(tmp_path):
    """The continuation start (fit up to 2 and 3 modes' band, then all) ends at the same optimum
    as a direct local solve on this well-posed chain (within 0.1 standard errors); a decreasing
    band list is refused with the key named."""
    from nlp.solve.continuation import band_continuation
    from nlp.errors import InputError
    case, ref, se = exact_optimum(tmp_path / "c")
    top = float(case.f[case.selected].max())
    logs = []
    _, res = band_continuation(case, [0.4 * top, 0.7 * top], log=logs.append)
    assert res.success and len(logs) == 3
    assert np.max(np.abs(res.z - ref.z) / se) < 0.1
    path = case.config.path
    with open(path) as fh:
        cfg = yaml.safe_load(fh)
    cfg["search"]["band_continuation"] = [5.0, 3.0]
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    with pytest.raises(InputError) as err:
        load_case(path)
    assert "search.band_continuation" in str(err.value)


def test_diagnosis_baseline_recentres_its_reduced_basis(tmp_path):
    """A diagnosis of a reduced case fits on the reduced backend (nlp.diagnosis.reduction):
    its baseline, refitted on bases re-centred on its own optimum, agrees with the exact
    sparse backend's optimum within 0.2 standard errors, and the last basis is checked
    against the exact FRF (the nominal basis is biased by more than 1 SE here)."""
    from nlp.diagnosis.fitting import best_fit, diagnosis_problem
    from nlp.diagnosis.reduction import recentre_baseline
    _, ref, se = exact_optimum(tmp_path / "exact")
    path_r, _ = write_chain_case(str(tmp_path / "reduced"), "reduced", reduced_cutoff=3.0)
    case_r = assemble(load_case(path_r))
    nominal = diagnosis_problem(case_r, case_r.target)
    assert nominal.backend == "reduced"
    res0 = best_fit(nominal, [case_r.params.z0])
    assert np.max(np.abs(res0.z - ref.z) / se) > 1.0

    def refit(c, z):
        pr = diagnosis_problem(c, c.target)
        return pr, best_fit(pr, [z])

    logs = []
    case_c, centre, z, info = recentre_baseline(case_r, refit, res0.z, logs.append)
    assert np.array_equal(case_c.basis_centre, centre)
    assert np.max(np.abs(z - ref.z) / se) < 0.2
    assert info["check"]["rms_log_error"] < info["check"]["noise"]
    assert any("reduced vs exact FRF at the baseline" in m for m in logs)


def test_a_basis_spanning_two_centres_is_accurate_at_both(tmp_path):
    """A basis at one centre misses the FRF far from it; the concatenated basis
    (nlp.frf.backends.reduced.enrich, a centre of several rows in basis_of) spans the bases
    at both centres, is M-orthonormal, and at each centre its FRF is as close to the exact
    sparse one as that centre's own basis, where one centre's basis misses the other's by
    ten times more."""
    from dataclasses import replace
    from nlp.diagnosis.reduction import basis_of
    from nlp.frf.backends.reduced import log_error
    from nlp.frf.backends.sparse import SparseFRF
    from nlp.frf.backends.system import LinearSystem
    path, _ = write_chain_case(str(tmp_path / "c"), "reduced", reduced_cutoff=1.5)
    case = assemble(load_case(path))
    z_a = case.params.z0.copy()
    z_b = z_a.copy()
    z_b[:GROUPS] = [0.6, -0.4, 0.5, -0.3, 0.4, -0.45]   # far from the nominal stiffnesses
    full = LinearSystem.from_model(case.model, case.damping, case.target)
    w = case.target.omega[::6]
    exact = {k: SparseFRF(full, case.damping, case.params, case.target,
                          "log_magnitude").frf(z, w) for k, z in (("a", z_a), ("b", z_b))}

    def error(psi, z, k):
        small = SparseFRF(full.project(psi), case.damping, case.params, case.target,
                          "log_magnitude")
        return log_error(exact[k], small.frf(z, w), np.ones_like(exact[k].real))[0]

    psi_a = basis_of(replace(case, basis_centre=z_a))
    psi_b = basis_of(replace(case, basis_centre=z_b))
    both = basis_of(replace(case, basis_centre=np.array([z_a, z_b])))
    M = case.model.M0
    np.testing.assert_allclose(both.T @ (M @ both), np.eye(both.shape[1]), atol=1e-9)
    for psi in (psi_a, psi_b):   # each input basis lies in the span: M-projection residual ~ 0
        rest = psi - both @ (both.T @ (M @ psi))
        assert np.linalg.norm(rest) < 1e-6 * np.linalg.norm(psi)
    assert both.shape[1] < psi_a.shape[1] + psi_b.shape[1] + 1
    far = error(psi_a, z_b, "b")
    assert far > 1e-4, f"the single basis should miss the far centre here ({far:.1e})"
    own_a, own_b = error(psi_a, z_a, "a"), error(psi_b, z_b, "b")
    assert own_b < far / 10   # a basis is accurate near its centre
    # the concatenation is as accurate at each centre as that centre's own basis
    assert error(both, z_a, "a") <= 1.01 * own_a and error(both, z_b, "b") <= 1.01 * own_b


@pytest.mark.parametrize("drop_r", [False, True])
def test_diagnosis_basis_carries_a_flexible_base(tmp_path, monkeypatch, drop_r):
    """A flexible base moves every support by the rigid translation r, which fixed-base modes
    and static vectors do not span: the diagnosis's reduced basis (reduction.basis_of) adds
    it, and the base family's FRF on it then follows the exact sparse one (without r it
    misses by several times the data noise of 0.01)."""
    import math
    import nlp.diagnosis.reduction as red
    from nlp.diagnosis.families import BaseFlexibility
    from nlp.diagnosis.fitting import case_references, diagnosis_problem, fit_target, with_values
    if drop_r:
        monkeypatch.setattr(red, "_support_translation", lambda case: np.zeros(case.model.n))
    H = {}
    for backend in ("sparse", "reduced"):
        folder = tmp_path / backend
        folder.mkdir()
        case = assemble(load_case(write_chain_case(str(folder), backend)[0]))
        idx = np.arange(case.f.size)
        target = fit_target(case, idx, np.full((len(case.channels), idx.size), 0.01))
        refs = case_references(case)
        pr = diagnosis_problem(case, target, [BaseFlexibility()], compile=False)
        assert pr.backend == backend
        z = with_values(pr, pr.z0[:-3], [2.0 * refs["m_ref"], math.log10(refs["k_ref"]) + 0.5,
                                         0.0])
        H[backend] = pr.channel_frfs(z, 2 * np.pi * case.f)
    miss = np.abs(np.log(H["reduced"] / H["sparse"])).max()
    assert (miss > 0.05) if drop_r else (miss < 0.02)
