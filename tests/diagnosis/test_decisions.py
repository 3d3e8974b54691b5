"""Decisions under model error, effects inside the model class, agreement between tests.

The data are simulated here, independently of the package: the direct FRF
-w^2 (K - w^2 M + j w C)^-1 b of a shear frame (conftest.shear_K) with 1 %
complex noise, written as an NPZ FRF file next to a case file.
"""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from scipy.linalg import eigh

import nlp.diagnosis.candidates as cand
import nlp.diagnosis.driver as D
import nlp.diagnosis.widen as W
from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.diagnosis.band import extra_modes, hot_spots, local_sigma
from nlp.diagnosis.candidates import candidates
from nlp.diagnosis.decide import better_unresolved, decide
from nlp.diagnosis.driver import diagnose
from nlp.diagnosis.evidence import (BIC_ACCEPT, BIC_TIE, HELD_OUT_FLOOR, STRONG_BIC, dispersion,
                                    evidence, held_out_excess, held_out_ok, scaled_delta_bic,
                                    tied)
from nlp.diagnosis.families import ZETA_S_MIN, SecondaryOscillator
from nlp.diagnosis.fitting import (best_fit, diagnosis_problem, fit_target, fit_windows,
                                   noise_sigma, normalised, signed)
from nlp.diagnosis.inside import dashpot_refit
from nlp.diagnosis.levels import (level_fit, level_location, release_location, released_story,
                                  shared_stiffness)
from nlp.diagnosis.others import refits_of_others, setup_others
from nlp.diagnosis.priors import (STORY_ZETA, damper_check, damping_excess, decompose_damping,
                                  modal_share, story_damping_ratio, story_patterns)
from nlp.diagnosis.refit import repolish
from nlp.diagnosis.resolution import (appendage_split, damping_pinned, estimate_resolution,
                                      resolved)
from nlp.diagnosis.verdict import classify, public
from nlp.frf.scatter import second_difference_factor
from support.diagnosis import F, baseline_fit, frame_matrices, write_case_yaml, write_frf
from support.frames import shear_K



def _accelerance(M, C, K, floor, rng, noise=0.01):
    """Accelerances of every floor to a force at `floor` (1-based), with noise."""
    n = M.shape[0]
    b = np.zeros(n)
    b[floor - 1] = 1.0
    H = np.empty((n, F.size), complex)
    for k, f in enumerate(F):
        w = 2 * np.pi * f
        H[:, k] = -w**2 * np.linalg.solve(K - w**2 * M + 1j * w * C, b)
    return H * (1 + noise * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))


@pytest.mark.slow  # a whole diagnosis: 20-40 s on 2 cores
def test_added_mass_appears_as_mass_outside_its_prior(tmp_path):
    rng = np.random.default_rng(1)
    m_nom, k_nom = [5.0, 5.0, 5.0], [3000.0, 2800.0, 2600.0]
    m = np.array([5.0, 7.5, 5.0])                # +2.5 kg on floor 2: +50 %, 5 prior sigmas
    k = np.array(k_nom) * [1.1, 0.95, 1.05]      # ordinary changes, inside the 25 % prior
    M, C, K = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, rng))
    cfg = write_case_yaml(tmp_path, m_nom, k_nom, [("frf.npz", 1)],
                {"prior": {"masses": 0.10, "stiffnesses": 0.25}},
                {"model": "rayleigh", "zeta": 0.015})
    res = diagnose(cfg, str(tmp_path / "out"), log=lambda *_: None)
    assert res["verdict"] == "missing_physics", res["summary"]
    assert [(f["physics"], f["location"]) for f in res["findings"]] == [("added_mass", {"floor": 2})]
    dm = res["findings"][0]["parameters"]["dm2"]
    se = res["findings"][0]["uncertainty"]["dm2"]
    assert abs(dm - 2.5) < max(3 * se, 0.1)
    assert se < dm
    # the ordinary stiffness changes are within the prior: not reported
    assert res["parameter_changes"] == []


@pytest.mark.slow  # a whole diagnosis: 20-40 s on 2 cores
def test_concentrated_damper_from_the_fitted_damping(tmp_path):
    rng = np.random.default_rng(2)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.01)
    e = np.array([-1.0, 1.0, 0.0])               # dashpot between floors 1 and 2
    C = C + 12.0 * np.outer(e, e)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 1)],
                {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                {"model": "general", "zeta": 0.01})
    res = diagnose(cfg, str(tmp_path / "out"), log=lambda *_: None)
    assert res["verdict"] == "missing_physics", res["summary"]
    found = [(f["physics"], f["location"]) for f in res["findings"]]
    assert ("local_damper", {"between": [1, 2]}) in found, res["summary"]
    f = next(f for f in res["findings"] if f["physics"] == "local_damper")
    # the excess over the other stories' share: 12 N s/m plus a1 k2 minus the median share
    assert 8.0 < f["parameters"]["c12"] < 16.0


@pytest.mark.slow  # two looks at one small case: 40-80 s on 2 cores
def test_widened_look_after_a_finding_starts_from_the_first(tmp_path, monkeypatch):
    """A coupling between floors 1 and 3, found in the first look. With the held-out rule
    for widening after a finding lowered so that it fires, the case is looked at again over
    3x wider windows: the first look's optima start that look (no second scatter search),
    its finding is re-proven alone (one refit) before the other candidates, and it is kept
    with its value (900 N/m within its uncertainty)."""
    rng = np.random.default_rng(3)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, _coupled(k, 900.0), 1, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 1)], {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                {"model": "rayleigh", "zeta": 0.015})
    searches, rounds, lines = [], [], []
    search, refit_all = D.scatter_best, D.refit_all
    monkeypatch.setattr(D, "scatter_best", lambda *a, **kw: searches.append(1) or search(*a, **kw))
    monkeypatch.setattr(D, "refit_all", lambda jobs, sc: rounds.append((len(lines), len(jobs)))
                        or refit_all(jobs, sc))
    monkeypatch.setattr(W, "HELD_LEFT", 0.0)
    res = diagnose(cfg, str(tmp_path / "out"), log=lines.append)
    widened = [i for i, line in enumerate(lines) if "findings leave the held-out" in line]
    assert widened, "the widened look after a finding did not run"
    assert len(searches) == 1                 # the first look's baseline search only
    wide = [n for at, n in rounds if at > widened[0]]
    assert wide and wide[0] == 1, rounds      # the seeded round refits the finding alone
    found = [(f["physics"], f["location"]) for f in res["findings"]]
    assert ("nonadjacent_coupling", {"between": [1, 3]}) in found, res["summary"]
    f = next(f for f in res["findings"] if f["physics"] == "nonadjacent_coupling")
    assert abs(f["parameters"]["k13"] - 900.0) < 3 * f["uncertainty"]["k13"] + 30


def test_damping_decomposition_recovers_story_dashpots():
    m, k = np.array([4.0, 5.0, 6.0, 5.0]), np.array([3000.0, 2500.0, 2000.0, 1500.0])
    M, K = np.diag(m), shear_K(k)
    c = np.array([0.5, 7.0, 0.25, 0.2])
    C = 0.3 * M + sum(ci * P for ci, P in zip(c, story_patterns(4)))
    a0, c_fit, left = decompose_damping(C, M)
    assert a0 == pytest.approx(0.3, rel=1e-9)
    assert np.allclose(c_fit, c, rtol=1e-9) and left < 1e-9
    # a stiffness-proportional C is the story pattern with c_s = a1 k_s
    _, c_fit, _ = decompose_damping(1e-3 * K, M)
    assert np.allclose(c_fit, 1e-3 * k, rtol=1e-9)


def _coupled(k, kc):
    K = shear_K(k)
    e = np.array([1.0, 0.0, -1.0])
    return K + kc * np.outer(e, e)


@pytest.mark.slow  # a whole diagnosis: 20-40 s on 2 cores
@pytest.mark.parametrize("same_structure", [True, False], ids=["consistent", "inconsistent"])
def test_finding_must_hold_on_the_other_test(tmp_path, same_structure):
    """A coupling between floors 1 and 3, tested with the shaker at floor 1 and at floor 2.
    On the same structure the finding holds on both; when the second test is of a frame
    without the coupling, it does not, and the verdict says so."""
    rng = np.random.default_rng(3)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    K = _coupled(k, 900.0)
    write_frf(tmp_path, "test1.npz", _accelerance(M, C, K, 1, rng))
    K2 = K if same_structure else shear_K(k)
    write_frf(tmp_path, "test2.npz", _accelerance(M, C, K2, 2, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("test1.npz", 1), ("test2.npz", 2)],
                {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                {"model": "rayleigh", "zeta": 0.015})
    res = diagnose(cfg, str(tmp_path / "out"), log=lambda *_: None)
    checks = [c for c in res["consistency"] if c["physics"] == "nonadjacent_coupling"]
    assert checks and checks[0]["test"] == "test2.npz"
    if same_structure:
        assert res["verdict"] == "missing_physics", res["summary"]
        assert res["findings"][0]["location"] == {"between": [1, 3]}
        assert checks[0]["holds"]
        there = checks[0]["there"]["k13"]
        assert abs(there - 900.0) < 3 * checks[0]["there_uncertainty"]["k13"] + 30
    else:
        assert not checks[0]["holds"]
        assert res["verdict"] == "ambiguous"
        assert all(f["physics"] != "nonadjacent_coupling" for f in res["findings"])
        assert res["unconfirmed"][0]["physics"] == "nonadjacent_coupling"
        assert any("does not hold on test2.npz" in s for s in res["summary"])


def _with_appendage(M, C, K, floor, mu, f_s, zeta=0.03):
    """M, C, K with an oscillator of mass mu * M[floor-1, floor-1] tuned to f_s [Hz] hung
    from `floor` (1-based), its DOF last."""
    n = M.shape[0]
    ms = mu * M[floor - 1, floor - 1]
    ks, cs = ms * (2 * np.pi * f_s) ** 2, 2 * zeta * ms * 2 * np.pi * f_s
    Ma, Ca, Ka = (np.zeros((n + 1, n + 1)) for _ in range(3))
    Ma[:n, :n], Ca[:n, :n], Ka[:n, :n] = M, C, K
    Ma[n, n] = ms
    for A, v in ((Ca, cs), (Ka, ks)):
        A[floor - 1, floor - 1] += v
        A[n, n] += v
        A[floor - 1, n] -= v
        A[n, floor - 1] -= v
    return Ma, Ca, Ka


@pytest.mark.slow  # two whole diagnoses: 40-80 s on 2 cores
@pytest.mark.parametrize("f_other", [5.0, 6.5], ids=["same", "retuned"])
def test_an_appendage_must_have_one_frequency_on_both_tests(tmp_path, f_other):
    """An appendage (mass ratio 0.1, 5 Hz) at floor 3, tested with the shaker at floors 1 and
    2: it holds on the other test. When the other test's oscillator is tuned to 6.5 Hz, its
    mass may agree but its frequency does not, so it is not one appendage: not confirmed."""
    rng = np.random.default_rng(8)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k)
    H1 = _accelerance(*_with_appendage(M, C, K, 3, 0.1, 5.0), 1, rng)[:3]
    H2 = _accelerance(*_with_appendage(M, C, K, 3, 0.1, f_other), 2, rng)[:3]
    write_frf(tmp_path, "test1.npz", H1)
    write_frf(tmp_path, "test2.npz", H2)
    cfg = write_case_yaml(tmp_path, m, k, [("test1.npz", 1), ("test2.npz", 2)],
                          {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                          {"model": "rayleigh", "zeta": 0.015})
    res = diagnose(cfg, str(tmp_path / "out"), log=lambda *_: None)
    checks = [c for c in res["consistency"] if c["physics"] == "secondary_oscillator"
              and c["location"] == {"floor": 3}]
    assert checks, res["summary"]
    if f_other == 5.0:
        assert checks[-1]["holds"]
        assert any(f["physics"] == "secondary_oscillator" and f["location"] == {"floor": 3}
                   for f in res["findings"])
    else:
        assert not checks[-1]["holds"]
        here, there = checks[-1]["here"]["f_s3"], checks[-1]["there"]["f_s3"]
        assert abs(here - there) > 3 * math.hypot(checks[-1]["here_uncertainty"]["f_s3"],
                                                  checks[-1]["there_uncertainty"]["f_s3"])
        assert all(f["physics"] != "secondary_oscillator" for f in res["findings"])


def test_quasi_likelihood_scales_evidence_by_the_remaining_misfit():
    # chi-square 1000 -> 500 on 100 points with 1 added parameter and reduced chi-square 5:
    # the quasi-likelihood BIC change is -500 / 5 + ln(100)
    phi = dispersion(500.0, 100)
    assert phi == pytest.approx(5.0)
    assert scaled_delta_bic(500.0, 1000.0, 1, 100, phi) == pytest.approx(-100 + math.log(100))
    assert dispersion(50.0, 100) == 1.0      # never below the noise-only value


def _result(physics, location, chi2, value=1.0, se=0.1):
    return {"physics": physics, "location": location, "parameters": {"p": value},
            "uncertainty": {"p": se}, "chi2": chi2, "held_out": 1.0, "at_bound": False}


def test_five_different_candidates_within_the_window_are_ambiguous():
    """Five physically different candidates whose chi-squares differ by less than phi x 6:
    inadequate model, candidates cannot be told apart; never one confident finding."""
    ref_chi, n_fit, nu = 4000.0, 200, 190
    # the best leaves chi-square 1900 on 189 dof: phi = 10.05; the others are within 50
    chis = [1900.0, 1910.0, 1925.0, 1940.0, 1950.0]
    kinds = [("added_mass", {"floor": 1}), ("sensor_gain", {"channel": "a1"}),
             ("nonadjacent_coupling", {"between": [1, 3]}), ("local_damper", {"between": [0, 1]}),
             ("added_mass", {"floor": 2})]
    results = [_result(p, loc, c) for (p, loc), c in zip(kinds, chis)]
    phi = decide(results, ref_chi, 10.0, nu, n_fit)
    assert phi == pytest.approx(1900.0 / 189)
    assert all(r["accepted"] for r in results)
    acc = sorted(results, key=lambda r: r["delta_bic"])
    ties = tied(acc)
    assert len(ties) == 4 and (50.0 / phi) < BIC_TIE
    assert classify(confirmed=[], unconfirmed=[], indistinct=[acc[0]] + ties, nonlin=False,
                     inside=[], adequate=False) == "ambiguous"
    # without the quasi-likelihood scale the same chi-squares would be 50 apart: one winner
    assert tied(acc, window=BIC_TIE / phi) == []


def test_a_lower_held_out_error_alone_accepts_nothing():
    """Retired 799498/62 (a null FRF file): a coupling 3.5 errors from zero at dBIC -2.4 cut
    the held-out chi-square from 2.99 to 1.15 through a few anti-resonance points. Acceptance
    needs the BIC drop of BIC_ACCEPT as well; with it, a 20 % held-out gain suffices."""
    ref_chi, nu, n_fit = 280.0, 290, 300      # reduced chi-square below 1: phi = 1
    weak = dict(_result("nonadjacent_coupling", {"between": [1, 4]}, ref_chi - 8.1,
                        value=-7.7, se=2.2), held_out=1.15)
    decide([weak], ref_chi, 2.99, nu, n_fit)
    # 1 parameter: dBIC = -8.1 + ln(300) = -2.4
    assert weak["delta_bic"] == pytest.approx(-8.1 + math.log(300))
    assert -BIC_ACCEPT < weak["delta_bic"] < 0 and weak["significant"]
    assert not weak["accepted"]
    strong = dict(_result("nonadjacent_coupling", {"between": [1, 4]}, ref_chi - 60.0,
                          value=-7.7, se=2.2), held_out=0.79 * 2.99)
    decide([strong], ref_chi, 2.99, nu, n_fit)
    assert strong["delta_bic"] <= -BIC_ACCEPT and strong["accepted"]
    strong["held_out"] = 0.81 * 2.99      # the fit improves, the held-out points do not
    decide([strong], ref_chi, 2.99, nu, n_fit)
    assert not strong["accepted"]


def test_held_out_points_already_at_their_noise_need_only_not_get_worse():
    """Retired 65424/48: a flexible base at dBIC -143.8 under a found added mass took the
    held-out chi-square 1.08 -> 0.99. Shoulders fitted to their noise cannot fall another
    20 %; there the candidate must only leave them no worse. Above HELD_OUT_FLOOR, and for
    an appendage, the 20 % cut stays the rule."""
    ref_chi, nu, n_fit = 1840.0, 1830, 1841
    r = dict(_result("base_flexibility", {}, ref_chi - 160.0), held_out=0.99)
    r["parameters"], r["uncertainty"] = {"log10_kb": 3.88}, {"log10_kb": 0.012}
    decide([r], ref_chi, 1.08, nu, n_fit)
    assert r["delta_bic"] <= -BIC_ACCEPT and r["significant"] and r["accepted"]
    r["held_out"] = 1.09                  # a hair worse on the points never fitted
    decide([r], ref_chi, 1.08, nu, n_fit)
    assert not r["accepted"]
    r["held_out"] = 0.81 * 1.6            # above the floor a 19 % cut is not enough
    decide([r], ref_chi, 1.6, nu, n_fit)
    assert 1.6 > HELD_OUT_FLOOR and not r["accepted"]
    assert held_out_ok(0.79 * 1.6, 1.6) and held_out_ok(1.3, 1.3) and not held_out_ok(1.31, 1.3)
    # an appendage can put its resonance on any bin: it keeps the 20 % cut
    a = dict(_result("secondary_oscillator", {"floor": 4}, ref_chi - 60.0, value=0.01,
                     se=0.001), held_out=1.05)
    decide([a], ref_chi, 1.08, nu, n_fit)
    assert a["delta_bic"] <= -BIC_ACCEPT and a["significant"] and not a["accepted"]
    assert held_out_ok(0.8 * 1.08, 1.08, "secondary_oscillator")


def test_an_appendage_proven_on_the_fitted_points_needs_only_leave_the_held_out_no_worse():
    """Retired 65424/13: a 0.05 appendage at floor 1, in the widened look (3x windows, few
    held-out points left), at dBIC -408 took the held-out chi-square only 1.34 -> 1.20. In
    40 retired nulls no appendage came within a factor 2 of STRONG_BIC, so one that far
    ahead on the fitted points is accepted if the held-out points are no worse."""
    ref_chi, nu, n_fit = 1840.0, 1830, 1841
    a = dict(_result("secondary_oscillator", {"floor": 1}, ref_chi - 430.0, value=0.01,
                     se=0.001), held_out=1.20)
    decide([a], ref_chi, 1.34, nu, n_fit)
    # scaled: phi = 1 (reduced chi-square below 1), one parameter of the test's result
    assert a["delta_bic"] == pytest.approx(-430.0 + math.log(n_fit))
    assert a["delta_bic"] <= -STRONG_BIC and a["significant"] and a["accepted"]
    a["held_out"] = 1.35                  # a hair worse on the points never fitted
    decide([a], ref_chi, 1.34, nu, n_fit)
    assert not a["accepted"]
    assert not held_out_ok(1.20, 1.34, "secondary_oscillator", -STRONG_BIC + 1.0)
    assert held_out_ok(1.20, 1.34, "secondary_oscillator", -STRONG_BIC)
    assert not held_out_ok(1.35, 1.34, "secondary_oscillator", -10 * STRONG_BIC)


def test_held_out_points_tell_apart_candidates_that_fit_the_windows_alike():
    """Two candidates 2 apart in scaled BIC, held-out mean 1.3 against 4.0 on 2,000 held-out
    residuals: the held-out data separate them by (4.0 - 1.3) x 2000 / 1.3 in chi-square."""
    a = dict(_result("secondary_oscillator", {"floor": 1}, 1000.0), held_out=1.3)
    b = dict(_result("added_mass", {"floor": 1}, 1002.0), held_out=4.0)
    decide([b, a], 4000.0, 10.0, 190, 200, n_held=2000)
    assert a["held_excess"] == 0.0
    assert b["held_excess"] == pytest.approx((4.0 - 1.3) * 2000 / 1.3)
    acc = sorted([b, a], key=evidence)
    assert acc[0] is a and tied(acc) == []
    # alike on the held-out points too: they cannot be told apart
    b["held_out"] = 1.3
    held_out_excess([a, b], 2000)
    assert tied(sorted([a, b], key=evidence)) == [b]


def test_current_model_re_solved_from_a_refit_leaves_a_local_minimum(tmp_path, rng):
    """A current model held away from its optimum (the start point, where a search stuck in a
    local minimum would leave it) and a refit whose baseline part lies near the optimum:
    the re-solve starts there and reaches the optimum of a solve from the true parameters;
    nothing changes when the current model is already there."""
    m, k = np.array([5.0, 4.0, 3.0]), np.array([4000.0, 3500.0, 3000.0])
    M, C, K = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, rng))
    cfg = write_case_yaml(tmp_path, 1.15 * m, 0.8 * k, [("frf.npz", 1)],
                {"stiffness_bounds": [-0.5, 1.0], "mass_bounds": [-0.5, 1.0]},
                {"model": "rayleigh", "zeta": 0.02})
    case = assemble(cfg)
    fit = fit_windows(cfg, case, 1)
    held = np.setdiff1d(fit_windows(cfg, case, 3), fit)
    pr = diagnosis_problem(case, fit_target(case, fit, noise_sigma(case, fit)), optimize=False)
    truth = pr.params.z_from_theta(np.concatenate([m / (1.15 * m) - 1, k / (0.8 * k) - 1,
                                                   pr.theta(pr.z0)[6:]]))
    ref = pr.solve(truth)
    assert ref.success
    sig_h = noise_sigma(case, held)
    stuck = {"current": [], "z": pr.z0, "chi": 2 * float(pr.objective(pr.z0)), "problem": pr,
             "held": float(np.mean(normalised(pr, pr.z0, case, held, sig_h) ** 2))}
    refit = {"z": np.concatenate([truth * 1.01, [0.0]]), "chi2": 2 * ref.f - 5.0}
    better = repolish(stuck, [refit], case, held, sig_h, pr.n_used)
    assert better is not None and better["chi"] == pytest.approx(2 * ref.f, rel=1e-6)
    # started from the refit's optimum without its candidate (this frame has one basin, so
    # the start is what shows the mechanism)
    assert np.allclose(better["result"].z0, np.clip(truth * 1.01, *pr.bounds))
    assert better["chi"] / (pr.n_used - pr.params.n_z) < 1.5   # inside the model class
    at_opt = dict(stuck, z=ref.z, chi=2 * ref.f)
    assert repolish(at_opt, [dict(refit, chi2=2 * ref.f - 0.5)], case, held, sig_h,
                    pr.n_used) is None


def test_effect_within_three_standard_errors_is_not_accepted():
    r = _result("sensor_gain", {"channel": "a1"}, 1000.0, value=0.05, se=0.02)
    decide([r], 4000.0, 10.0, 190, 200)
    assert not r["significant"] and not r["accepted"]


def _appendage(mu, se_mu, f_se, zeta, zeta_se):
    return {"physics": "secondary_oscillator", "location": {"floor": 4},
            "parameters": {"mu4": mu, "f_s4": 7.7, "zeta_s4": zeta},
            "uncertainty": {"mu4": se_mu, "f_s4": f_se, "zeta_s4": zeta_se},
            "chi2": 2000.0, "held_out": 1.0, "at_bound": False, "score": 600.0}


def test_a_flexible_base_whose_mass_and_dashpot_the_data_leave_open_is_still_found():
    """A flexible base is measured by its flexibility 1/k_b; its dashpot and its mass only
    shape the base resonance (like an appendage's damping) and trade against the
    stiffness, so an open c_base or m_base is reported as not determined and never
    refuses it. The base is proven by its chi-square drop over phi (> 9), not by the
    Wald error of 1/k_b: a drop of 1000 with 1/k_b within one error of zero is found,
    a drop of 8 is not."""
    lk = 5.0  # log10 of the stiffness; 10^-x flexibility with 0.01 decades of error

    def base(se_m, se_c, se_k=0.01, chi2=2000.0):
        return {"physics": "base_flexibility", "location": {},
                "parameters": {"m_base": 2.0, "log10_kb": lk, "c_base": 3.0},
                "uncertainty": {"m_base": se_m, "log10_kb": se_k, "c_base": se_c},
                "chi2": chi2, "held_out": 1.0, "at_bound": False, "score": 600.0}

    open_c, open_m = base(0.1, 12.0), base(5.0, 0.5)
    wald_weak, small_drop = base(0.1, 0.5, se_k=1.0), base(0.1, 0.5, chi2=2992.0)
    decide([open_c, open_m, wald_weak, small_drop], 3000.0, 6.0, 1700, 1771)
    assert open_c["accepted"] and open_m["accepted"] and wald_weak["accepted"]
    assert public(open_m)["not_determined"] == ["m_base"]
    assert not small_drop["significant"] and "chi-square drop" in small_drop["why_not"]
    pub = public(open_c)
    assert pub["not_determined"] == ["c_base"] and "c_base" not in pub["parameters"]


def test_an_appendage_refit_also_starts_at_each_unexplained_resonance():
    """The extra modes of the whole band are starts of the appendage refit when they lie
    inside its frequency box and away from the scan's own start; they are not part of
    the candidate's identity (same repr, equal candidates)."""
    e = SecondaryOscillator(1, 8.17, resonances=(9.52, 30.0, 8.2, 3.0))
    assert e.starts({}) == [[0.01, 9.52, 0.02]]
    assert e == SecondaryOscillator(1, 8.17) and repr(e) == repr(SecondaryOscillator(1, 8.17))
    assert SecondaryOscillator(1, 8.17).starts({}) == []


def test_an_appendage_whose_damping_the_data_leave_open_is_still_found():
    """The appendage's mass ratio is 10 standard errors from zero; its damping ratio
    is not determined (its own resonance lies between the fitted windows). The
    damping never decides: the appendage is accepted and reported without it, so no
    reported parameter has an error above its value. An undetermined frequency (not
    a nuisance) or a mass ratio whose error exceeds it still refuses it. The mass ratio
    is tested by the chi-square drop (likelihood ratio over phi > 9), not by its Wald
    error: 2.5 errors from zero with a drop of 1000 is found; a drop of 8 is not."""
    ok = _appendage(0.05, 0.005, 0.05, 0.0245, 0.11)
    freq_open = _appendage(0.05, 0.005, 9.0, 0.0245, 0.11)
    mass_open = _appendage(0.05, 0.06, 0.05, 0.0245, 0.11)
    wald_weak = _appendage(0.05, 0.02, 0.05, 0.0245, 0.11)
    small_drop = dict(_appendage(0.05, 0.005, 0.05, 0.0245, 0.11), chi2=2992.0)
    decide([ok, freq_open, mass_open, wald_weak, small_drop], 3000.0, 6.0, 1700, 1771)
    assert ok["accepted"] and not freq_open["accepted"] and not mass_open["accepted"]
    assert "f_s4" in freq_open["why_not"] and "mu4" in mass_open["why_not"]
    assert wald_weak["significant"] and wald_weak["accepted"]
    assert not small_drop["significant"] and "chi-square drop" in small_drop["why_not"]
    pub = public(ok)
    assert pub["not_determined"] == ["zeta_s4"] and set(pub["parameters"]) == {"mu4", "f_s4"}
    assert all(pub["uncertainty"][n] < abs(v) for n, v in pub["parameters"].items())
    assert "zeta_s4" in pub["statement"] and "not determined" in pub["statement"]
    # a determined damping ratio is reported with its error, as before
    firm = _appendage(0.05, 0.005, 0.05, 0.0245, 0.004)
    decide([firm], 3000.0, 6.0, 1700, 1771)
    assert firm["accepted"] and "not_determined" not in public(firm)


def test_an_appendage_whose_damping_sits_on_its_lower_bound_is_refused():
    """A determined damping ratio within one standard error of the box's lower bound
    (retired 83439/50: 0.00102 +- 0.00033 against 0.001) is a line as sharp as the
    model allows, not a resonance: refused, with the reason. Two errors above the
    bound it stands; an undetermined damping (error above its value) does not decide."""
    assert SecondaryOscillator(4, 5.0).spec({})["lower"][2] == ZETA_S_MIN
    assert damping_pinned(0.00102, 0.00033, 0.001)
    assert not damping_pinned(0.001 + 2 * 0.00033, 0.00033, 0.001)
    assert not damping_pinned(0.0245, 0.11, 0.001)
    sharp = _appendage(0.05, 0.005, 0.05, 0.00102, 0.00033)
    clear = _appendage(0.05, 0.005, 0.05, 0.00175, 0.00033)
    decide([sharp, clear], 3000.0, 6.0, 1700, 1771)
    assert not sharp["accepted"] and "lower bound" in sharp["why_not"]
    assert clear["accepted"]


def test_a_better_unresolved_appendage_is_said_beside_the_finding():
    """An appendage refused only because its mode sits inside the bandwidth of a structural
    mode, but ahead of the accepted coupling on BIC and on the held-out points (retired
    146094/12): the coupling is still the best accepted candidate, and the appendage is
    returned as a better explanation the data cannot resolve. One that trails the coupling,
    or one refused for its errors, is not."""
    split = {"separation_hz": 0.49, "half_widths_hz": 0.68, "resolution_hz": 0.05,
             "appendage_mode_hz": 8.39, "nearest_mode_hz": 7.90, "resolved": False}
    coupling = dict(_result("nonadjacent_coupling", {"between": [1, 4]}, 2000.0), held_out=1.89)
    ahead = dict(_appendage(0.05, 0.005, 0.05, 0.0245, 0.004), chi2=1600.0, held_out=1.18,
                 split=split)
    behind = dict(ahead, location={"floor": 3}, chi2=2150.0, held_out=2.0)
    shaky = dict(ahead, location={"floor": 2}, uncertainty=dict(ahead["uncertainty"], mu4=0.2))
    results = [coupling, ahead, behind, shaky]
    decide(results, 3000.0, 6.0, 1700, 1771, n_held=2000)
    assert coupling["accepted"] and not ahead["accepted"] and ahead["unresolved"]
    assert "not a separate resonance" in ahead["why_not"]
    assert not shaky["unresolved"]          # refused on its own errors, not on resolution
    out = better_unresolved(results, coupling, 6.0)
    assert [r["location"] for r in out] == [{"floor": 4}]
    assert out[0]["instead_of"] == "nonadjacent_coupling {'between': [1, 4]}"
    # resolved, it would simply be accepted and ranked ahead of the coupling
    res = dict(ahead, split=dict(split, resolved=True))
    decide([coupling, res], 3000.0, 6.0, 1700, 1771, n_held=2000)
    assert res["accepted"] and better_unresolved([coupling, res], coupling, 6.0) == []


def test_extra_mode_found_with_its_channels_and_nothing_else():
    """A 3-storey frame 'measured' with an appendage on floor 3 tuned to 11 Hz (a mode the
    3-DOF model lacks); the model is the frame alone. The extra mode is reported at its
    frequency on the channels that see it; the frame's own modes and zeros are not."""
    rng = np.random.default_rng(5)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.01)
    H_model = _accelerance(M, C, K, 1, rng, noise=0.0)
    ms, fs = 0.05, 11.0                       # 1 % of a floor, 0.5 % damping
    ks, cs = ms * (2 * np.pi * fs) ** 2, 2 * 0.005 * ms * 2 * np.pi * fs
    Ma = np.diag([5.0, 5.0, 5.0, ms])
    Ka = np.zeros((4, 4))
    Ka[:3, :3] = K
    Ka[2, 2] += ks
    Ka[2, 3] = Ka[3, 2] = -ks
    Ka[3, 3] = ks
    Ca = np.zeros((4, 4))
    Ca[:3, :3] = C
    Ca[2, 2] += cs
    Ca[2, 3] = Ca[3, 2] = -cs
    Ca[3, 3] = cs
    H_meas = _accelerance(Ma, Ca, Ka, 1, rng, noise=0.01)[:3]
    Lx, La = np.log(np.abs(H_meas)), np.log(np.abs(H_model))
    sig = local_sigma(Lx)
    modes = extra_modes(F, Lx, La, sig, np.ones_like(Lx, bool))
    assert len(modes) == 1, modes
    assert abs(modes[0]["frequency_hz"] - fs) < 0.3
    assert 2 in modes[0]["channels"]          # floor 3 carries the appendage
    # the model itself, measured with noise: no extra mode
    H_same = _accelerance(M, C, K, 1, rng, noise=0.01)
    Lx = np.log(np.abs(H_same))
    assert extra_modes(F, Lx, La, local_sigma(Lx), np.ones_like(Lx, bool)) == []


def test_hot_spot_of_an_appendage_between_two_modes():
    """A 3-storey frame 'measured' with a 5 % appendage on floor 3 tuned to 3.2 Hz, between
    its first two modes (1.70 and 4.66 Hz); the model is the frame alone, and the points
    within 4 % of its modes are the fitted ones. The largest misfit off them lies at the
    appendage (within 15 %: the residual peaks on the resonance-antiresonance pair it
    makes); the frame measured with noise has none; fitted points are never one."""
    rng = np.random.default_rng(5)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.02)
    fn = np.sqrt(eigh(K, M, eigvals_only=True)) / (2 * np.pi)
    H_model = _accelerance(M, C, K, 1, rng, noise=0.0)
    ms, fs = 0.25, 3.2
    ks, cs = ms * (2 * np.pi * fs) ** 2, 2 * 0.02 * ms * 2 * np.pi * fs
    Ma, Ka, Ca = np.diag([5.0, 5.0, 5.0, ms]), np.zeros((4, 4)), np.zeros((4, 4))
    Ka[:3, :3], Ca[:3, :3] = K, C
    for A, v in ((Ka, ks), (Ca, cs)):
        A[2, 2] += v
        A[2, 3] = A[3, 2] = -v
        A[3, 3] = v
    sigma = 0.01                               # 1 % complex noise: ln|H| scatter 0.01
    H_meas = _accelerance(Ma, Ca, Ka, 1, rng, noise=sigma)[:3]
    r = (np.log(np.abs(H_meas)) - np.log(np.abs(H_model))) / sigma
    fitted = np.flatnonzero(np.any([np.abs(F / f - 1) <= 0.04 for f in fn], axis=0))
    hot = hot_spots(F, r, np.ones_like(r, bool), fitted)
    assert hot and abs(hot[0] / fs - 1) < 0.15, hot
    assert all(np.min(np.abs(F[fitted] - h)) > 0 for h in hot)
    H_same = _accelerance(M, C, K, 1, rng, noise=sigma)
    r0 = (np.log(np.abs(H_same)) - np.log(np.abs(H_model))) / sigma
    assert hot_spots(F, r0, np.ones_like(r0, bool), fitted) == []


def test_local_sigma_of_a_windowed_estimate_counts_its_correlated_bins():
    """Errors of a Hann-windowed Welch estimate: each average's cross-spectrum noise is a
    product of two Hann-smoothed white spectra, so neighbouring bins correlate. The
    local scatter read with the window's second-difference factor recovers the point
    standard deviation (np.std of the errors themselves); read as independent bins it
    understates it by sqrt(6 / 2.5) = 1.55."""
    rng = np.random.default_rng(3)
    n, taps = 20000, np.array([-0.25, 0.5, -0.25])   # a Hann window in the frequency domain

    def smoothed():
        e = rng.normal(size=n + 2) + 1j * rng.normal(size=n + 2)
        return np.convolve(e, taps, "valid")

    u = sum(np.real(smoothed() * np.conj(smoothed())) for _ in range(8))
    u = 0.01 * u / np.std(u)
    hann = np.median(local_sigma(u[None], d2_factor=second_difference_factor("hann")))
    white = np.median(local_sigma(u[None]))
    assert abs(hann / 0.01 - 1) < 0.06
    assert abs(0.01 / white - math.sqrt(6 / 2.5)) < 0.1


def test_modal_share_of_a_story_dashpot():
    """A dashpot that is the only damping supplies all of every mode's damping;
    Rayleigh damping has no excess anywhere; a 12 N s/m dashpot over 1 % Rayleigh
    damping dominates (the phi^T C phi of each mode checked by hand-built sums)."""
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.01)
    P = story_patterns(3)
    only = 7.0 * P[1]
    share = modal_share(M, K, only, damping_excess(only, M, K)[0])
    np.testing.assert_allclose(share[1], 1.0, rtol=1e-10)
    assert np.all(share[[0, 2]] == 0.0)
    np.testing.assert_allclose(modal_share(M, K, C, damping_excess(C, M, K)[0]), 0.0, atol=1e-9)
    C2 = C + 12.0 * P[1]
    ex = damping_excess(C2, M, K)[0]
    _, phi = eigh(K, M)
    drift = phi[1] - phi[0]
    by_hand = ex[1] * drift ** 2 / np.array([phi[:, r] @ C2 @ phi[:, r] for r in range(3)])
    np.testing.assert_allclose(modal_share(M, K, C2, ex)[1], by_hand, rtol=1e-10)
    assert by_hand.max() > 0.5


def test_appendage_split_of_a_tuned_absorber_and_what_resolves_it():
    """An undamped absorber of mass ratio mu tuned to a 1-DOF main mass splits its mode into
    (w/w0)^2 = 1 + mu/2 +- sqrt(mu + mu^2/4) (Den Hartog). A tiny one (mu = 0.0004) splits
    by less than the half-power half-widths of 2 % damping: one reshaped peak; mu = 0.05 splits
    by about f sqrt(mu), far wider: a resonance of its own."""
    m0, f0 = 10.0, 3.0
    k0 = m0 * (2 * np.pi * f0) ** 2
    for mu, expect in ((0.0004, False), (0.05, True)):
        ms = mu * m0
        ks = ms * (2 * np.pi * f0) ** 2
        M = np.diag([m0, ms])
        K = np.array([[k0 + ks, -ks], [-ks, ks]])
        exact = f0 * np.sqrt(1 + mu / 2 + np.array([-1, 1]) * np.sqrt(mu + mu ** 2 / 4))
        sep, half, fa, fb = appendage_split(M, K, 1e-9 * K)
        assert sep == pytest.approx(exact[1] - exact[0], rel=1e-6)
        assert sorted([fa, fb]) == pytest.approx(exact, rel=1e-6)
        # 2 % damping of the main mass and the absorber
        C = np.array([[2 * 0.02 * np.sqrt(k0 * m0), 0.0], [0.0, 0.0]]) \
            + 2 * 0.02 * np.sqrt(ks * ms) * np.array([[1.0, -1.0], [-1.0, 1.0]])
        sep, half, _, _ = appendage_split(M, K, C)
        assert resolved(sep, half, 0.001) == expect
    # a Hann estimate resolves 1.5 bins (its equivalent noise bandwidth), a rectangular one 1
    f = np.arange(0.0, 50.0, 0.025)
    assert estimate_resolution(f, "hann") == pytest.approx(1.5 * 0.025, rel=1e-3)
    assert estimate_resolution(f, "boxcar") == pytest.approx(0.025)


def test_a_damped_appendage_whose_half_power_bands_stand_apart_is_resolved():
    """Two uncoupled oscillators (a structural mode at 8.08 Hz, 1 %, and an appendage at
    8.73 Hz, 5 %, as fitted on retired 83439/50): the half-widths are zeta f of each,
    0.081 + 0.437 Hz, under the 0.65 Hz between them, so the half-power bands do not
    overlap and the appendage is a resonance of its own, although its full bandwidth
    (0.87 Hz) exceeds the separation. Closer than the half-widths, or than the
    estimate's resolution, it is not."""
    m = np.array([10.0, 0.5])
    f = np.array([8.08, 8.73])
    zeta = np.array([0.01, 0.05])
    k = m * (2 * np.pi * f) ** 2
    c = 2 * zeta * np.sqrt(k * m)
    sep, half, fa, fb = appendage_split(np.diag(m), np.diag(k), np.diag(c))
    # modal_parameters reads f = |lambda| / 2 pi: the undamped natural frequencies
    assert (fa, fb) == pytest.approx((8.73, 8.08), rel=1e-9)
    assert sep == pytest.approx(0.65, rel=1e-9)
    assert half == pytest.approx(0.01 * 8.08 + 0.05 * 8.73, rel=1e-9)
    assert 2 * 0.05 * 8.73 > sep                  # the old rule's full bandwidth refused it
    assert resolved(sep, half, 0.006)
    assert not resolved(sep, half, 0.7)           # a coarse estimate does not resolve it
    assert not resolved(0.9 * half, half, 0.006)


class _DampedFrame:
    """Just what damper_check asks of a problem: M, K, C at z = (a0, c_1..c_n), bounds."""

    def __init__(self, m, k):
        self.M, self.K = np.diag(m), shear_K(k)
        self.bounds = (np.zeros(len(k) + 1), np.full(len(k) + 1, np.inf))

    def matrices(self, z):
        C = z[0] * self.M + sum(c * P for c, P in zip(z[1:], story_patterns(len(z) - 1)))
        return self.M, self.K, C


def test_no_damper_claimed_next_to_a_story_dashpot_pinned_at_zero():
    """Story 2 carries a dashpot far beyond the others' share. With stories 1 and 3 damped
    it is a concentrated damper; with story 1's dashpot at zero (the non-negative
    decomposition on its bound) story 2 may carry story 1's damping, and nothing is
    claimed."""
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    pr = _DampedFrame(m, k)
    cov = np.diag(np.full(4, 1e-6))
    z = np.array([0.1, 3.0, 15.0, 2.6])          # c/k: 1e-3, 5.4e-3, 1e-3
    info, flagged = damper_check(pr, z, cov)
    assert [d["story"] for d in flagged] == [2] and info["pinned_stories"] == []
    z_pinned = np.array([0.1, 0.0, 15.0, 2.6])
    info, flagged = damper_check(pr, z_pinned, cov)
    assert flagged == [] and info["pinned_stories"] == [1]


def test_damper_away_from_a_pinned_story_is_claimed_against_the_unpinned_stories():
    """Four stories, story 1 pinned at zero and story 3 far above the others: the damper is
    claimed, and its share is measured against stories 2 and 4 only (the pinned zero would
    halve the median c / k and double the ratio)."""
    m, k = np.array([5.0, 5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0, 2400.0])
    pr = _DampedFrame(m, k)
    cov = np.diag(np.full(5, 1e-6))
    c = np.array([0.0, 2.8, 20.0, 3.6])          # c/k: 0, 1e-3, 7.7e-3, 1.5e-3
    info, flagged = damper_check(pr, np.concatenate([[0.1], c]), cov)
    assert info["pinned_stories"] == [1] and [d["story"] for d in flagged] == [3]
    ref = np.median([2.8 / 2800.0, 3.6 / 2400.0])
    assert flagged[0]["ratio"] == pytest.approx(20.0 / 2600.0 / ref, rel=1e-9)
    assert flagged[0]["excess"] == pytest.approx(20.0 - ref * 2600.0, rel=1e-9)


def test_story_damping_ratio_by_hand():
    """One story's dashpot as a damping ratio of its story oscillator over the median
    modal damping ratio of the structure without it: C = a1 K + e P_2, and without the
    dashpot (C = a1 K, stiffness-proportional) every mode has zeta_r = a1 omega_r / 2, so
    the ratio is e / (2 sqrt(k_2 m_2)) / (a1 median(omega) / 2). With the dashpot left
    in its own yardstick (removed = 0) the median is that of a1 K + e P_2, by a separate
    eigen-solution."""
    m, k = np.array([4.0, 6.0, 5.0]), np.array([3000.0, 2500.0, 2000.0])
    M, K = np.diag(m), shear_K(k)
    a1 = 0.002
    w2, phi = eigh(K, M)
    e = np.array([0.0, 7.0, 0.0])
    C = a1 * K + 7.0 * story_patterns(3)[1]
    got, zmed = story_damping_ratio(M, K, C, e)
    assert zmed[1] == pytest.approx(a1 * np.median(np.sqrt(w2)) / 2, rel=1e-10)
    assert got[1] == pytest.approx(7.0 / (2 * np.sqrt(2500.0 * 6.0)) / zmed[1], rel=1e-10)
    assert got[0] == 0.0 and got[2] == 0.0
    z_in = np.median(np.diag(phi.T @ C @ phi) / (2 * np.sqrt(w2)))
    got_in, zmed_in = story_damping_ratio(M, K, C, e, removed=np.zeros(3))
    assert zmed_in[1] == pytest.approx(z_in, rel=1e-10) and z_in > zmed[1]


def test_damper_must_stand_out_one_standard_error_below_its_estimate():
    """Story 2's excess dashpot, as a damping ratio of its story, is just over STORY_ZETA
    times the median modal damping. Determined to 1 %, it is a concentrated damper; with a
    standard error that puts it below STORY_ZETA one error lower, it is not, though it
    stands well over DETERMINED standard errors from zero."""
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    pr = _DampedFrame(m, k)
    base = np.array([0.1, 3.0, 0.0, 2.6])
    M, K, _ = pr.matrices(base)

    def ratio(c2, minus=0.0):
        C = pr.matrices(np.r_[base[:2], c2, base[3]])[2]
        ex = damping_excess(C, M, K)[0]
        return story_damping_ratio(M, K, C, ex - np.r_[0.0, minus, 0.0], removed=ex)[0][1]

    target = STORY_ZETA + 0.05
    lo_, hi_ = 3.0, 200.0           # the c_2 whose ratio is target, by bisection (monotone)
    for _ in range(80):
        mid = 0.5 * (lo_ + hi_)
        lo_, hi_ = (mid, hi_) if ratio(mid) < target else (lo_, mid)
    z = np.r_[base[:2], hi_, base[3]]
    ex = damping_excess(pr.matrices(z)[2], M, K)[0][1]
    info, flagged = damper_check(pr, z, np.diag([1e-8, 1e-8, (0.01 * ex) ** 2, 1e-8]))
    assert [d["story"] for d in flagged] == [2]
    assert flagged[0]["story_zeta_ratio"] == pytest.approx(target, abs=1e-6)
    se = ex / 8                     # 8 errors from zero, but one error lower it is below the line
    assert ratio(hi_, se) < STORY_ZETA
    info, flagged = damper_check(pr, z, np.diag([1e-8, 1e-8, se ** 2, 1e-8]))
    assert flagged == []


def test_candidates_ranked_high_on_the_other_test_are_refitted(tmp_path):
    """The score test of one test of the structure can rank the true effect low; the
    other test's ranking adds it to the refits, so both tests take the same path.
    Here this test's own list is emptied: the coupling must come from the other test,
    whose score at its own baseline optimum ranks it first."""
    rng = np.random.default_rng(5)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    K = _coupled(k, 900.0)
    write_frf(tmp_path, "test1.npz", _accelerance(M, C, K, 1, rng))
    write_frf(tmp_path, "test2.npz", _accelerance(M, C, K, 2, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("test1.npz", 1), ("test2.npz", 2)],
                {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                {"model": "rayleigh", "zeta": 0.015})
    case = assemble(cfg)
    idx = fit_windows(cfg, case, 1)
    pr = diagnosis_problem(case, fit_target(case, idx, noise_sigma(case, idx)))
    z = best_fit(pr, [pr.z0]).z
    others = setup_others(cfg)
    here = {repr(e): 1.0 for e in candidates(case)}
    jobs = refits_of_others(others, {"current": [], "z": z}, [], here, top=1)
    assert [e.family for _, e in jobs].count("nonadjacent_coupling") == 1
    assert any(e.family == "nonadjacent_coupling" for _, e in jobs[:1])
    # and the other test's optimum is cached for the model it was fitted for
    assert () in others[0]["at"]


@pytest.mark.slow  # two whole diagnoses: 40-80 s on 2 cores
def test_two_tests_give_the_same_finding_whichever_is_updated(tmp_path):
    """The same structure (coupling 1-3, floor-2 sensor reading 12 % low) tested with the
    shaker at floors 1 and 2: diagnosing either test, with the other as its second test,
    names the same effects with values that agree within 3 combined standard errors.
    (A property of the joint selection; on data this clean the old one-test path gave it
    too. Cristallo, where it did not, is in notes.md.)"""
    rng = np.random.default_rng(11)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, _ = frame_matrices(m, k)
    K = _coupled(k, 900.0)
    gain = np.array([1.0, 0.88, 1.0])[:, None]
    for name, floor in (("test1.npz", 1), ("test2.npz", 2)):
        write_frf(tmp_path, name, gain * _accelerance(M, C, K, floor, rng))
    params = {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}}
    damping = {"model": "rayleigh", "zeta": 0.015}
    out = []
    for order in ([("test1.npz", 1), ("test2.npz", 2)], [("test2.npz", 2), ("test1.npz", 1)]):
        folder = tmp_path / order[0][0].split(".")[0]
        folder.mkdir()
        for name, _ in order:
            (folder / name).symlink_to(tmp_path / name)
        res = diagnose(write_case_yaml(folder, m, k, order, params, damping), str(folder / "out"),
                       log=lambda *_: None)
        out.append({(f["physics"], repr(f["location"])): f for f in res["findings"]
                    if "uncertainty" in f})
    assert out[0] and set(out[0]) == set(out[1])
    for key, f in out[0].items():
        g = out[1][key]
        for n, v in f["parameters"].items():
            assert abs(v - g["parameters"][n]) <= 3 * math.hypot(f["uncertainty"][n],
                                                                  g["uncertainty"][n])


@pytest.mark.slow  # a general-C baseline and one structured refit: ~20 s
def test_story_dashpots_refitted_directly_recover_non_proportional_damping(tmp_path):
    """Rayleigh damping plus story dashpots of uneven size and a damper at story 3: the
    structured refit (C = a0 M + story dashpots) fits as well as the general C, and its
    story dashpots stand within 4 of their own standard errors of the true ones (true
    c_s = a1 k_s + dashpot_s, the story pattern of a stiffness-proportional C)."""
    rng = np.random.default_rng(5)
    m, k = np.array([5.0, 4.5, 4.0, 4.0]), np.array([3200.0, 3000.0, 2700.0, 2400.0])
    M, C_r, K = frame_matrices(m, k, zeta=0.01)
    a1 = C_r[0, 1] / -k[1]                        # from the off-diagonal of a1 K
    a0 = (C_r[0, 0] - a1 * (k[0] + k[1])) / m[0]
    dash = np.array([1.5, 0.5, 14.0, 1.0])        # N s/m; story 3 is a damper
    C = C_r + sum(c * P for c, P in zip(dash, story_patterns(4)))
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 2, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 2)], {"fixed": {"m1": 5.0}},
                {"model": "general", "zeta": 0.01}, channels=4)
    case, state = baseline_fit(cfg)
    s = dashpot_refit(case, state)
    assert s["fits"], s
    Mz, _, Cz = s["problem"].matrices(s["z"])
    a0_fit, c_fit, left = decompose_damping(Cz, Mz)
    assert left < 1e-9                             # C is of the family by construction
    se = np.sqrt(np.diag(s["cov"]))
    # the decision variables behind the dashpots: c_s = a1_ref theta_s k0_s, linear
    d = s["problem"].damping
    sd = s["problem"].params.slices()[2]
    T = s["problem"].params.T
    se_theta = np.sqrt(np.clip(np.diag(T @ s["cov"] @ T.T), 0, None))[sd][1:]
    se_c = d.a1_ref * k * se_theta
    c_true = a1 * k + dash
    assert np.all(np.abs(c_fit - c_true) < 4 * se_c + 0.02 * c_true), (c_fit, c_true, se_c)
    assert se.size == s["problem"].params.n_z
    # a general C that no story-dashpot family holds (a strong 1-3 dashpot) is refused
    e13 = np.array([1.0, 0.0, -1.0, 0.0])
    C13 = C_r + 30.0 * np.outer(e13, e13)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C13, K, 2, rng))
    case, state = baseline_fit(load_case(str(tmp_path / "case.yaml")))
    s13 = dashpot_refit(case, state)
    assert not s13["fits"] and s13["excess"] > s13["limit"], s13


@pytest.mark.slow  # four short level fits and two shared-stiffness refits: ~20 s
def test_levels_compared_by_the_fit_with_shared_stiffnesses(tmp_path):
    """Two levels of one linear frame fit each other's masses and stiffnesses (scaled
    chi-square rise within BIC's price); a story 2 that stiffens by 6 % at the second
    level does not (the rise is many times the price), and freeing one story's stiffness
    at a time names story 2: its refit takes nearly all of the rise (over 0.8 of it), the
    others under half."""
    rng = np.random.default_rng(3)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.015)
    write_frf(tmp_path, "lo.npz", _accelerance(M, C, K, 1, rng))
    write_frf(tmp_path, "same.npz", _accelerance(M, C, K, 1, rng))
    write_frf(tmp_path, "stiff.npz", _accelerance(M, C, shear_K(k * [1.0, 1.06, 1.0]), 1, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("lo.npz", 1)], {"fixed": {"m1": 5.0}},
                {"model": "general", "zeta": 0.015})
    cfg = replace(cfg, solver=replace(cfg.solver, options={"max_iter": 3000}))
    ref = level_fit(cfg, cfg.data.file)
    for name, changed in (("same.npz", False), ("stiff.npz", True)):
        lv = level_fit(cfg, str(tmp_path / name), ref["z"])
        lr = shared_stiffness(ref, lv)
        assert lr["converged"]
        assert (lr["excess"] > lr["limit"]) == changed, (name, lr)
        if changed:
            assert lr["excess"] > 5 * lr["limit"]
            # the score test linearises at the reference model, whose weakly determined
            # damping entries move with the noise weights: it named story 2 here until the
            # file noise spread its peak bias (b8c390f), then story 3 (scores 494, 778,
            # 2631), while story 2's release took 83,977 of the rise of 83,979. It decides
            # only where a release refit did not converge; here it must rank story 2 above 1
            scores = level_location(ref, lv)[1]
            assert scores[1] > scores[0]
            release = release_location(ref, lv, lr)
            assert all(ok for _, ok in release)
            drops = [d for d, _ in release]
            assert released_story(release) == 1
            # story 2 freed is the other level's own model up to its damping: the drop
            # takes the whole rise (less what the level's own masses would add)
            assert drops[1] > 0.8 * lr["rise"]
            assert max(drops[0], drops[2]) < 0.5 * lr["rise"]


@pytest.mark.slow  # eight short level fits and twenty held refits: ~30 s
def test_levels_of_a_linear_frame_share_their_stiffnesses_as_a_chi_square(tmp_path):
    """A linear frame at two levels whose reference FRF is 4x noisier than the other. The
    quieter level's chi-square rise under the reference's masses and stiffnesses carries
    the reference's error too (about k (1 + 16) on average); the likelihood ratio of one
    set of masses and stiffnesses for both levels is a chi-square of k = 5 degrees of
    freedom (k1-k3, m2, m3 free; m1 weighed): mean 5, SD of a mean of four 1.6. Its
    bound at the information-weighted set must come near that."""
    rng = np.random.default_rng(5)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.015)
    excess, rise = [], []
    for _ in range(4):
        write_frf(tmp_path, "lo.npz", _accelerance(M, C, K, 1, rng, noise=0.04))
        write_frf(tmp_path, "hi.npz", _accelerance(M, C, K, 1, rng, noise=0.01))
        write_case_yaml(tmp_path, m, k, [("lo.npz", 1)], {"fixed": {"m1": 5.0}},
              {"model": "general", "zeta": 0.015})
        # bin-by-bin FRFs: no analyzer window, so the noise model is the scatter alone
        case = yaml.safe_load((tmp_path / "case.yaml").read_text())
        case["data"]["window"] = "none"
        (tmp_path / "case.yaml").write_text(yaml.safe_dump(case, sort_keys=False))
        cfg = load_case(str(tmp_path / "case.yaml"))
        ref = level_fit(cfg, cfg.data.file)
        lr = shared_stiffness(ref, level_fit(cfg, str(tmp_path / "hi.npz"), ref["z"]))
        assert lr["converged"] and lr["held_parameters"] == 5
        assert lr["excess"] == min(lr["bounds"].values())
        excess.append(lr["excess"])
        rise.append(lr["rise"])
    assert 1.5 < np.mean(excess) < 10.0, excess
    assert np.mean(rise) > 2 * np.mean(excess), rise


def test_a_release_location_needs_every_other_refit_converged():
    """An unconverged refit's drop is only a lower bound: the largest drop names its story
    only when the others converged, whichever converged itself."""
    assert released_story([(5.0, True), (40.0, False), (9.0, True)]) == 1
    assert released_story([(5.0, True), (40.0, True), (9.0, False)]) is None
    assert released_story([(50.0, True), (40.0, True), (9.0, True)]) == 0


def test_no_held_out_points_gives_an_empty_residual(tmp_path):
    """Windows widened over the whole band leave no held-out shoulder: the normalised
    residual there is empty, not a CasADi map over zero frequencies (held-back 610789/24
    stopped with 'Degenerate map operation')."""
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, np.random.default_rng(0)))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 1)], {"fixed": {"m1": 5.0}},
                {"model": "rayleigh", "zeta": 0.015})
    case = assemble(cfg)
    fit = fit_windows(cfg, case, 1)
    pr = diagnosis_problem(case, fit_target(case, fit, noise_sigma(case, fit)))
    r = normalised(pr, pr.z0, case, np.array([], int), np.zeros((3, 0)))
    assert r.shape == (3, 0)


def test_appendage_scan_adds_a_candidate_away_from_the_resonances(monkeypatch):
    """A tiny oscillator's score peaks next to every resonance (it splits the peak): when
    a floor's best scan frequency lies within 10 % of a fitted resonance, the best one
    away from all of them is refitted too. Scores here are a stand-in profile: a spike
    at the 2 Hz resonance and a broad bump at 3.5 Hz, between the resonances."""
    f = np.linspace(0.5, 12.0, 2301)
    sel = np.concatenate([np.flatnonzero(np.abs(f - fr) <= 0.04 * fr) for fr in (2.0, 5.0, 8.0)])
    case = SimpleNamespace(f=f, selected=sel, model=SimpleNamespace(n=2))

    def score(f0):
        return 100.0 * math.exp(-((f0 - 2.0) / 0.05) ** 2) + 40.0 * math.exp(-((f0 - 3.5) / 0.5) ** 2)

    monkeypatch.setattr(cand, "diagnosis_problem", lambda *a, **k: None)
    monkeypatch.setattr(cand, "with_values", lambda pr, z, v: v[1])
    monkeypatch.setattr(cand, "score_at", lambda pr, f0, k: (score(f0), 1.0))
    out = cand.scan_secondary(case, None, [], None)
    assert [e.floor for e, _ in out] == [1, 1, 2, 2]
    near, away = out[0][0].f0, out[1][0].f0
    assert abs(near / 2.0 - 1) < 0.1
    assert abs(away / 3.5 - 1) < 0.05
    # a best frequency away from every resonance needs no second candidate
    monkeypatch.setattr(cand, "score_at", lambda pr, f0, k: (40.0 * math.exp(-((f0 - 3.5) / 0.5) ** 2), 1.0))
    assert len(cand.scan_secondary(case, None, [], None)) == 2


@pytest.mark.parametrize("residual", ["log_magnitude", "complex"])
def test_signed_residuals_carry_the_objective_chi_square(tmp_path, residual):
    """The spread of the baseline chi-square (diagnosis.spread) is read from signed: its sum
    of squares must be the chi-square the solver minimises (2 x objective), for the
    log-magnitude residual and for the complex one (real and imaginary parts)."""
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, np.random.default_rng(4)))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 1)], {"fixed": {"m1": 5.0}},
                {"model": "rayleigh", "zeta": 0.015})
    cfg = replace(cfg, objective=replace(cfg.objective, residual=residual))
    case = assemble(cfg)
    fit = fit_windows(cfg, case, 1)
    sig = noise_sigma(case, fit)
    pr = diagnosis_problem(case, fit_target(case, fit, sig), optimize=False)
    z = pr.z0
    r = signed(pr, z, case, fit, sig)
    assert r.shape[0] == (6 if residual == "complex" else 3)
    assert np.sum(r ** 2) == pytest.approx(2 * float(pr.objective(z)), rel=1e-6)
    # and the residual map's mean square (ln|Ha/Hx|, or |ln(Ha/Hx)| / sqrt(2) with the phase,
    # equal to first order in the misfit)
    assert np.mean(r ** 2) == pytest.approx(np.mean(normalised(pr, z, case, fit, sig) ** 2),
                                            rel=1e-9 if residual == "log_magnitude" else 0.05)


def test_case_fitting_every_frequency_holds_out_the_points_between_windows(tmp_path, rng):
    """A case whose selection is every frequency (``method: all``) leaves the diagnosis no
    held-out shoulders; it then fits the half-power windows and holds out the rest, so the
    held-out tests have data no fit used (the windows are those of a half-power case)."""
    m, k = np.array([5.0, 4.0, 3.0]), np.array([4000.0, 3500.0, 3000.0])
    M, C, K = frame_matrices(m, k)
    write_frf(tmp_path, "frf.npz", _accelerance(M, C, K, 1, rng))
    cfg = write_case_yaml(tmp_path, m, k, [("frf.npz", 1)], {"fixed": {"m1": 5.0}},
                          {"model": "rayleigh", "zeta": 0.015})
    windows = fit_windows(cfg, assemble(cfg), 1)
    cfg_all = replace(cfg, frequencies=replace(cfg.frequencies, method="all"))
    case = assemble(cfg_all)
    lines = []
    points = D.points_stage(cfg_all, case, 1, (), lines.append)
    assert np.array_equal(points.fit, np.intersect1d(windows, case.selected))
    assert points.held.size > 0 and np.intersect1d(points.held, points.fit).size == 0
    assert np.array_equal(np.union1d(points.fit, points.held), case.selected)
    assert any("fits every frequency" in ln for ln in lines)
    # with a hot frequency between two modes (the widened look) the windows and the hot
    # window are fitted and the rest still held out (it was empty: held-out misfits NaN)
    hot = (float(np.sqrt(case.f[points.fit].min() * case.f[points.fit].max())),)
    hot_pts = D.points_stage(cfg_all, case, 1, hot, lines.append)
    assert np.isin(points.fit, hot_pts.fit).all() and hot_pts.fit.size > points.fit.size
    assert hot_pts.held.size > 0 and np.intersect1d(hot_pts.held, hot_pts.fit).size == 0
    assert np.array_equal(np.union1d(hot_pts.fit, hot_pts.held), case.selected)


def test_a_refusal_names_its_reason_and_the_parameter_on_its_bound():
    """The round log says why each refit was refused; on a bound it names the parameter."""
    from nlp.diagnosis.nuisance import why_refused
    r = {"significant": True, "at_bound": True, "on_bound": ["m_base"],
         "parameters": {"m_base": 60000.0, "log10_kb": 9.1, "c_base": 0.0},
         "delta_bic": -1.5e5, "held_out": 221.0}
    assert why_refused(r) == "m_base = 6e+04 on the bound of its family's range"
    assert why_refused({**r, "at_bound": False, "delta_bic": -4.0}).startswith(
        "its scaled BIC change -4.0 is above")
    assert why_refused({**r, "significant": False, "why_not": "x"}) == "x"


def test_a_widened_look_refutes_a_finding_that_predicts_its_shoulders_worse():
    """The first look's finding, re-proved first on 3x windows: refused there with held-out
    shoulders worse than the wider model without it, it is refuted (the wider look stands,
    the finding is unconfirmed); refused while leaving them no worse, or accepted, the first
    look's rule (keep every finding) still decides."""
    found = [{"physics": "secondary_oscillator", "location": {"floor": 4}}]
    ref = dict(_result("secondary_oscillator", {"floor": 4}, 500.0), accepted=False,
               held_out=24.5, score=0.0, delta_bic=-800.0,
               parameters={"mu4": 0.04, "f_s4": 3.5}, uncertainty={"mu4": 0.005, "f_s4": 0.15})
    sel = SimpleNamespace(tried=[ref])
    gone = W.refuted_on_wider(sel, 6.3)
    assert gone["widened"] == {"held_out": 24.5, "held_out_without": 6.3}
    result = {"findings": [], "unconfirmed": [public(gone)]}
    assert W.keeps_findings(result, found)
    assert W.refuted_on_wider(SimpleNamespace(tried=[dict(ref, held_out=6.0)]), 6.3) is None
    assert W.refuted_on_wider(SimpleNamespace(tried=[dict(ref, accepted=True)]), 6.3) is None
    assert not W.keeps_findings({"findings": [], "unconfirmed": []}, found)
