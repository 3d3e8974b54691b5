"""Noise model per FRF route: null cases (physics inside the model class) fit to
a reduced chi-square near 1 on every route.

Records and FRFs are simulated here by tests/sim_frame.py (scipy lsim of a
3-storey frame at 10x the recorded rate, noise on the input and every output),
independently of the package's FRF and time-stepping code; the package only
estimates, weighs and fits.
"""

from dataclasses import replace
import math

import numpy as np
import pytest
import yaml

import sim_frame as sf
from nlp import noise
from nlp.case import assemble, build_problem
from nlp.config import load_case
from nlp.search import SearchConfig, scatter_search

FS_FINE, DECIM = 1000.0, 10


def _case_yaml(folder, data):
    """A shear-frame case whose nominal values are 8-15 % off the truth; m1 weighed."""
    case = {"name": "null", "model": {"type": "shear_frame",
                                      "masses": [5.0, 5.0, 4.5],
                                      "stiffnesses": [3500.0, 3600.0, 2300.0]},
            "parameters": {"fixed": {"m1": float(sf.MASSES[0])}},
            "damping": {"model": "general", "zeta": 0.02},
            "data": data, "frequencies": {"method": "half_power", "k": 2.0},
            "search": {"starts": 8, "seed": 0, "workers": 1}}
    path = folder / "case.yaml"
    path.write_text(yaml.safe_dump(case))
    return str(path)


def _records_case(tmp_path, x, y, extra):
    fs = FS_FINE / DECIM
    names = ["a1", "a2", "a3"]
    sf.write_records(tmp_path / "rec.csv", fs, x, y, names)
    data = {"type": "time_histories", "file": "rec.csv",
            "input": {"column": "ag", "quantity": "ground_acceleration"},
            "channels": [{"name": nm, "floor": i + 1, "quantity": "acceleration", "column": nm}
                         for i, nm in enumerate(names)], **extra}
    return _case_yaml(tmp_path, data)


def _reduced_chi2(path):
    """Baseline fit weighted by the noise model: chi-square / degrees of freedom."""
    case = assemble(load_case(path))
    sig = noise.sigma_ln(case, case.selected)
    case = replace(case, target=replace(case.target, weight=1.0 / sig))
    pr = build_problem(case)
    best = scatter_search(pr, SearchConfig(starts=8, seed=0), progress=None).best
    return 2 * best.f / (pr.n_used - pr.params.n_z), noise.noise_model(case), case


def test_one_segment_chirp_null_case_has_reduced_chi2_near_one(tmp_path):
    rng = np.random.default_rng(1)
    M, C, K = sf.frame()
    x, y = sf.simulate(sf.chirp_input(FS_FINE, 0.5, 20.0, 60, 5, 20), FS_FINE, M, C, K)
    x, y = sf.add_noise(x, y, 0.02, rng)
    chi2, model, case = _reduced_chi2(_records_case(tmp_path, x, y, {"nperseg": "all"}))
    assert model.route == "transient"
    # the scatter of ln|H| really varies along frequency (peaks against shoulders)
    s = model.sigma_ln[:, (case.f > 1) & (case.f < 9)]
    assert s.max() / s.min() > 10
    assert 0.8 <= chi2 <= 1.3, chi2


def test_welch_null_case_has_reduced_chi2_near_one(tmp_path):
    rng = np.random.default_rng(2)
    M, C, K = sf.frame()
    x, y = sf.simulate(sf.random_input(FS_FINE, 20.0, 300, rng), FS_FINE, M, C, K)
    x, y = sf.add_noise(x, y, 0.02, rng)
    chi2, model, _ = _reduced_chi2(_records_case(tmp_path, x, y, {"nperseg": 4096}))
    assert model.route == "welch" and 10 < model.n_averages < 14
    assert 0.8 <= chi2 <= 1.3, chi2


def test_frf_file_null_case_has_reduced_chi2_near_one(tmp_path):
    """FRF file without coherence: relative complex noise that grows away from
    the peaks (as an additive output noise does), found by the local scatter."""
    rng = np.random.default_rng(3)
    M, C, K = sf.frame()
    f = np.arange(0.5, 12.0, 0.01)
    H = sf.frf_exact(M, C, K, f)
    rel = 0.01 * (1 + 3 * f / f[-1])                     # 1 % to 4 %
    H = H * (1 + rel / math.sqrt(2) * (rng.standard_normal(H.shape)
                                       + 1j * rng.standard_normal(H.shape)))
    (tmp_path / "frf.csv").write_text("".join(
        f"{fk:.6f}," + ",".join(repr(complex(h)).strip("()") for h in col) + "\n"
        for fk, col in zip(f, H.T)))
    data = {"file": "frf.csv", "format": "complex",
            "channels": [{"name": f"a{i + 1}", "floor": i + 1, "output": "absolute_accelerance",
                          "column": i} for i in range(3)]}
    chi2, model, case = _reduced_chi2(_case_yaml(tmp_path, data))
    assert model.route == "scatter"
    lo, hi = model.sigma_ln[:, case.f < 2].mean(), model.sigma_ln[:, case.f > 10].mean()
    assert 2.0 < hi / lo < 5.0                      # follows the 1 % -> 4 % ramp
    assert 0.8 <= chi2 <= 1.3, chi2


def test_transient_variance_matches_monte_carlo():
    """Var ln|Y/X| of one noisy DFT bin against the errors-in-variables formula."""
    rng = np.random.default_rng(4)
    U, Hk = 2.0 + 1.0j, 0.5 - 0.3j
    s_nx, s_ny = 0.04, 0.01                          # noise powers of the bins
    n = 200000
    nx = math.sqrt(s_nx / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    ny = math.sqrt(s_ny / 2) * (rng.standard_normal(n) + 1j * rng.standard_normal(n))
    est = np.log((Hk * U + ny) / (U + nx))
    p_xx = np.array([abs(U) ** 2 + s_nx])
    p_yy = np.array([[abs(Hk * U) ** 2 + s_ny]])
    var = noise.var_ln_transient(p_xx, p_yy, np.array([s_nx]), np.array([[s_ny]]))[0, 0]
    assert np.var(est.real) == pytest.approx(var, rel=0.05)
    assert np.var(est.imag) == pytest.approx(var, rel=0.05)


def test_welch_overlap_correction():
    """Hann at 50 % overlap: rho_1 = 1/6, so n_eff = n_d / (1 + 2 (1 - 1/n_d) / 36)."""
    n_d, n_eff = noise.welch_averages(1024 * 10, 1024, 512, "hann")
    assert n_d == 19
    assert n_eff == pytest.approx(19 / (1 + 2 * (1 - 1 / 19) / 36), rel=1e-3)
    assert noise.welch_averages(4096, 1024, 0, "hann") == (4, 4.0)
    assert noise.kernel_moment("hann", 4096) == pytest.approx(1 / 3, rel=1e-4)


def test_frf_file_with_coherence_null_case(tmp_path):
    """An .npz FRF file with its coherence and averaging count: H1 simulated here
    by averaging independent noisy blocks (complex Gaussian input and noise on
    input and outputs), fitted with the coherence route."""
    rng = np.random.default_rng(5)
    M, C, K = sf.frame()
    f = np.arange(0.5, 12.0, 0.01)
    H = sf.frf_exact(M, C, K, f)
    n_avg, nx, ny = 30, 0.05, 0.3

    def cgauss(*shape):
        return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / math.sqrt(2)

    U = cgauss(n_avg, f.size)
    X = U + nx * cgauss(n_avg, f.size)
    Y = H[None] * U[:, None] + ny * np.abs(H).mean(axis=1)[None, :, None] * cgauss(n_avg, 3, f.size)
    s_xx = np.mean(np.abs(X) ** 2, axis=0)
    s_xy = np.mean(np.conj(X)[:, None] * Y, axis=0)
    s_yy = np.mean(np.abs(Y) ** 2, axis=0)
    np.savez(tmp_path / "frf.npz", f=f, H=s_xy / s_xx, coherence=np.abs(s_xy) ** 2 / (s_xx * s_yy),
             n_averages=n_avg)
    data = {"file": "frf.npz", "channels": [{"name": f"a{i + 1}", "floor": i + 1,
                                             "output": "absolute_accelerance", "column": i}
                                            for i in range(3)]}
    chi2, model, _ = _reduced_chi2(_case_yaml(tmp_path, data))
    assert model.route == "frf_coherence" and model.n_averages == n_avg
    assert 0.8 <= chi2 <= 1.3, chi2


def test_chirp_noise_above_last_mode_is_not_a_mode(tmp_path):
    """fmax at the top of the excitation band (20 Hz), last mode at 7.4 Hz: the
    half-power selection keeps the three modes only."""
    rng = np.random.default_rng(6)
    M, C, K = sf.frame()
    x, y = sf.simulate(sf.chirp_input(FS_FINE, 0.5, 20.0, 60, 5, 20), FS_FINE, M, C, K)
    x, y = sf.add_noise(x, y, 0.02, rng)
    path = _records_case(tmp_path, x, y, {"nperseg": "all"})
    raw = yaml.safe_load(open(path))
    raw["frequencies"]["fmax"] = 20.0
    yaml.safe_dump(raw, open(path, "w"))
    case = assemble(load_case(path))
    modes = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)) / (2 * np.pi)
    f_sel = case.f[case.selected]
    near = np.min(np.abs(f_sel[:, None] - modes[None, :]) / modes[None, :], axis=1)
    assert near.max() < 0.1, f_sel[near >= 0.1]
    assert all(np.any(np.abs(f_sel - fr) < 0.01 * fr) for fr in modes)
