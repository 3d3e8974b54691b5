"""Model discrepancy (nlp.diagnosis.discrepancy): a resonance outside the model class is
kept as a modal term and reported with the channels that see it; an appendage's resonance
is left to the candidate search. FRFs simulated here in numpy, not by the package."""

import numpy as np
import pytest
import yaml

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from scipy.linalg import eigh

from nlp.diagnosis.checks import whole_band
from nlp.diagnosis.discrepancy import beyond_band, described, refute_in_discrepancy
from nlp.diagnosis.families import ExtraMode
from nlp.diagnosis.widen import HOT_WINDOW
from nlp.diagnosis.driver import baseline_stage, discrepancy_stage, points_stage

from support.diagnosis import F, baseline_fit, frame_matrices, write_case_yaml, write_frf
from nlp.testing.frames import shear_K

m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
F_X = 9.5          # the resonance outside the model [Hz]


def _frame_frf(M, C, K, rng):
    H = np.empty((3, F.size), complex)
    for i, f in enumerate(F):
        w = 2 * np.pi * f
        H[:, i] = (-w**2 * np.linalg.solve(K - w**2 * M + 1j * w * C, np.eye(K.shape[0])[0]))[:3]
    return H * (1 + 0.005 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))


def _diagnose_to_discrepancy(folder, H):
    write_frf(folder, "frf.npz", H)
    write_case_yaml(folder, m, k, [("frf.npz", 1)],
                    {"fixed": {f"m{i + 1}": 5.0 for i in range(3)}},
                    {"model": "rayleigh", "zeta": 0.015})
    # the three storey modes, as a real case says (an extra peak is not a fourth mode)
    doc = yaml.safe_load((folder / "case.yaml").read_text())
    doc["frequencies"]["n_peaks"] = 3
    (folder / "case.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    cfg = load_case(str(folder / "case.yaml"))
    case = assemble(cfg)
    log = []
    points = points_stage(cfg, case, 1, (), log.append)
    base = baseline_stage(cfg, case, points, None, log.append)
    return discrepancy_stage(cfg, case, points, base, 1, log.append), log


@pytest.mark.slow
def test_a_resonance_outside_the_model_is_kept_as_discrepancy(tmp_path):
    """An out-of-plane mode seen by floors 1 and 3 only: a modal term -w^2 r_c / (w_x^2 - w^2
    + 2 j zeta w_x w) added to the sway frame's accelerances."""
    rng = np.random.default_rng(11)
    M, C, K = frame_matrices(m, k)
    H = _frame_frf(M, C, K, rng)
    w, wx, zx = 2 * np.pi * F, 2 * np.pi * F_X, 0.01
    r = np.array([0.004, 0.0, -0.003])
    H += r[:, None] * (-w**2) / (wx**2 - w**2 + 2j * zx * wx * w)
    (case, points, base), log = _diagnose_to_discrepancy(tmp_path, H)
    assert len(case.discrepancy) == 1, log
    assert not case.outside_class, log      # one resonance is a subsystem's, not a class
    d = described(points.base, base.res.z, case.discrepancy)[0]
    assert abs(d["frequency_hz"] - F_X) < 3 * d["frequency_se_hz"] + 0.01
    assert set(d["channels"]) == {"a1", "a3"}, d


@pytest.mark.slow
def test_an_appendages_resonance_is_left_to_the_candidates(tmp_path):
    """An appendage of 10 % of a floor at floor 2 tuned to F_X: its resonance is the
    family's, so no discrepancy is kept."""
    rng = np.random.default_rng(12)
    M3, C3, K3 = frame_matrices(m, k)
    ms, ws, zs = 0.5, 2 * np.pi * F_X, 0.01
    ks, cs = ms * ws**2, 2 * zs * ms * ws
    M, C, K = (np.zeros((4, 4)) for _ in range(3))
    M[:3, :3], C[:3, :3], K[:3, :3] = M3, C3, K3
    M[3, 3] = ms
    for A, v in ((K, ks), (C, cs)):
        A[1, 1] += v
        A[3, 3] += v
        A[1, 3] -= v
        A[3, 1] -= v
    H = _frame_frf(M, C, K, rng)
    (case, _, _), log = _diagnose_to_discrepancy(tmp_path, H)
    # the resonance is either the updated model's third mode moved (left to the candidates
    # at once) or offered to the families, where the appendage explains it
    assert case.discrepancy == (), log
    if any("resonances the model lacks" in line for line in log):
        assert any("secondary_oscillator" in line and "explains it" in line for line in log), log


def test_an_appendage_tuned_into_a_discrepancy_window_is_refused():
    """An accepted appendage whose resonance lies within HOT_WINDOW of a model-discrepancy
    mode is refused (it takes up that mode's misfit); one elsewhere in the band is kept."""
    modes = (ExtraMode(28.9, ("a1", "a2")),)
    inside = 28.9 * (1 - 0.9 * HOT_WINDOW)
    outside = 28.9 * (1 - 1.1 * HOT_WINDOW)
    results = [{"physics": "secondary_oscillator", "location": {"floor": k}, "accepted": True,
                "significant": True, "why_not": "",
                "parameters": {f"mu{k}": 0.01, f"f_s{k}": f, f"zeta_s{k}": 0.02}}
               for k, f in ((1, inside), (2, outside))]
    results.append({"physics": "sensor_gain", "location": {"channel": "a1"}, "accepted": True,
                    "significant": True, "why_not": "", "parameters": {"gain_a1": 0.05}})
    refute_in_discrepancy(modes, results, lambda s: None)
    assert [r["accepted"] for r in results] == [False, True, True]
    assert "model discrepancy at 28.90 Hz" in results[0]["why_not"]


def _beyond(tmp_path, H, fmax, fixed):
    """The whole band's extra modes of a baseline fit up to fmax [Hz], split by beyond_band."""
    write_frf(tmp_path, "frf.npz", H)
    write_case_yaml(tmp_path, m, k, [("frf.npz", 1)], {"fixed": fixed},
                    {"model": "rayleigh", "zeta": 0.015})
    doc = yaml.safe_load((tmp_path / "case.yaml").read_text())
    doc["frequencies"].update(fmax=fmax, n_peaks=2)
    (tmp_path / "case.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    case, base = baseline_fit(load_case(str(tmp_path / "case.yaml")))
    pr, z = base["problem"], base["z"]
    whole = whole_band(case, pr, z, pr, z, np.arange(0))
    return beyond_band(case, pr, z, whole["extra_modes"])


def test_a_resonance_beyond_the_fitted_band_is_reported_with_its_channels(tmp_path):
    """A modal term at 11 Hz on floors 1 and 3 (none on floor 2), above a band that ends at
    9 Hz: model discrepancy seen by a1 and a3, not fitted."""
    rng = np.random.default_rng(5)
    M, C, K = frame_matrices(m, k)
    H = _frame_frf(M, C, K, rng)
    w, wx, zx = 2 * np.pi * F, 2 * np.pi * 11.0, 0.005
    r = np.array([0.004, 0.0, -0.003])
    H += r[:, None] * (-w**2) / (wx**2 - w**2 + 2j * zx * wx * w)
    extra, beyond = _beyond(tmp_path, H, 9.0, {f"m{i + 1}": 5.0 for i in range(3)})
    assert len(beyond) == 1, (extra, beyond)
    b = beyond[0]
    assert abs(b["frequency_hz"] - 11.0) <= 0.05 and b["fitted"] is False
    assert set(b["channels"]) == {"a1", "a3"}
    assert b["band_hz"][1] <= 9.0 and "above the fitted band" in b["statement"]
    assert all(abs(e["frequency_hz"] - 11.0) > 0.2 for e in extra)


def test_a_model_mode_moved_beyond_the_band_is_not_discrepancy(tmp_path):
    """The data's third storey mode moved up 4 % (k3 15 % stiffer than the fixed nominal),
    beyond a band that ends at 6 Hz: the model's own mode, moved, stays an extra mode."""
    rng = np.random.default_rng(6)
    M, C, K = frame_matrices(m, k * np.array([1.0, 1.0, 1.15]))
    fixed = {f"m{i + 1}": 5.0 for i in range(3)} | {f"k{i + 1}": float(k[i]) for i in range(3)}
    extra, beyond = _beyond(tmp_path, _frame_frf(M, C, K, rng), 6.0, fixed)
    f3 = np.sqrt(eigh(K, M, eigvals_only=True))[-1] / (2 * np.pi)
    assert beyond == [], beyond
    assert any(abs(e["frequency_hz"] / f3 - 1) < 0.01 for e in extra), (f3, extra)


def test_a_term_whose_damping_sits_at_its_bound_is_not_a_resonance(monkeypatch):
    """resonant() keeps a modal term whose damping the data measure and drops one within
    one standard error of the box's lower bound (5e-4), the appendage's rule; a damping the
    data leave open (error above its value) is not pinned."""
    import nlp.diagnosis.discrepancy as D

    modes = [ExtraMode(6.0 + j, ("a1",)) for j in range(4)]
    # (zeta, its standard error) per mode
    fits = [(0.0005, 0.0002), (0.0008, 0.0005), (0.01, 0.001), (0.0008, 0.001)]
    names = [n for md in modes for n in md.names]
    theta = np.array([v for (z, _), md in zip(fits, modes) for v in (md.f0, z, 1e-3)])
    se = np.array([v for (_, e), md in zip(fits, modes) for v in (0.01, e, 1e-4)])

    class Pr:
        params = type("P", (), {"names": names})

        def theta(self, z):
            return theta

    monkeypatch.setattr(D, "quasi_se", lambda pr, z: (se, None))
    kept = D.resonant(Pr(), None, modes)
    assert [md.f0 for md in kept] == [8.0, 9.0]


def test_a_spent_budget_keeps_the_untested_resonances_and_claims_no_family(monkeypatch):
    """kept_modes with the time budget spent after the first resonance: that one is offered
    to the families (here one explains it), the rest are kept as model discrepancy without
    being offered, and returned as untested."""
    import nlp.diagnosis.discrepancy as D

    modes = [ExtraMode(6.0 + j, ("a1",)) for j in range(3)]
    asked = []
    monkeypatch.setattr(D, "resonant", lambda pr, z, ms: list(ms))
    monkeypatch.setattr(D, "explained_by", lambda case, tg, pr, res, ms, e, *a, **kw:
                        asked.append(e.f0) or [{"physics": "secondary_oscillator",
                                                "location": {"floor": 1},
                                                "restriction": {"scaled_rise": 1.0,
                                                                "limit": 9.0}}])
    calls = iter([False, True, True])
    wide = type("W", (), {"target": None, "held": None, "sig_held": None})
    keep, untested, outside = D.kept_modes(None, wide, None, type("R", (), {"z": None}), modes,
                                           100, lambda *a: None, spent=lambda: next(calls))
    assert asked == [6.0]
    assert [m.f0 for m in keep] == [7.0, 8.0] and untested == [7.0, 8.0] and not outside


class _Fitted:
    """A fitted model stand-in: theta and parameter names of ExtraMode terms."""

    def __init__(self, modes, fz):
        self.params = type("P", (), {"names": [n for md in modes for n in md.names]})
        self._theta = np.array([v for (f, zeta), md in zip(fz, modes)
                                for v in [f, zeta] + [0.0] * len(md.channels)])

    def theta(self, z):
        return self._theta


def test_resonances_count_once_where_their_half_power_bands_overlap():
    """Two terms whose half-power half-widths zeta f overlap are one peak read twice; apart,
    they are two. Separation 0.05 Hz at 2 Hz and zeta 1 %: 0.05 > 0.02 + 0.0205, two;
    at zeta 2 %: 0.05 < 0.04 + 0.041, one."""
    import nlp.diagnosis.discrepancy as D

    modes = [ExtraMode(f, ("a1",)) for f in (2.0, 2.05, 5.0)]
    assert D.distinct_count(_Fitted(modes, [(2.0, 0.01), (2.05, 0.01), (5.0, 0.01)]), None,
                            modes) == 3
    assert D.distinct_count(_Fitted(modes, [(2.0, 0.02), (2.05, 0.02), (5.0, 0.02)]), None,
                            modes) == 2


def test_as_many_resonances_missing_as_the_model_has_is_a_class_not_a_subsystem(monkeypatch):
    """outside_class at n_missing >= n_own > 0; kept_modes then keeps every resonant term
    and asks no family; with fewer missing, the families are asked."""
    import nlp.diagnosis.discrepancy as D

    assert D.outside_class(3, 3) and D.outside_class(4, 3)
    assert not D.outside_class(2, 3) and not D.outside_class(1, 0)
    modes = [ExtraMode(f, ("a1",)) for f in (2.0, 4.0, 6.0)]
    fitted = _Fitted(modes, [(f, 0.01) for f in (2.0, 4.0, 6.0)])
    asked = []
    monkeypatch.setattr(D, "resonant", lambda pr, z, ms: list(ms))
    monkeypatch.setattr(D, "explained_by", lambda case, tg, pr, res, ms, e, *a, **kw:
                        asked.append(e.f0) or [])
    wide = type("W", (), {"target": None, "held": None, "sig_held": None})
    res = type("R", (), {"z": None})
    keep, untested, outside = D.kept_modes(None, wide, fitted, res, modes, 100,
                                           lambda *a: None, n_own=3)
    assert outside and keep == modes and asked == [] and untested == []
    keep, untested, outside = D.kept_modes(None, wide, fitted, res, modes, 100,
                                           lambda *a: None, n_own=4)
    assert not outside and asked == [2.0, 4.0, 6.0] and keep == modes


@pytest.mark.slow
def test_a_torsionally_flexible_frame_is_a_class_of_motion_outside_the_model(tmp_path):
    """An eccentric 3-storey frame, x and theta per floor (stiffness centre 0.15 m off the
    mass centre, radius of gyration 0.4 m, torsional to translational frequency ratio 0.75:
    torsionally flexible), x-accelerometers 0.35 m off the centre line reading x + 0.35
    theta, force in x at floor 1. Its three torsion-dominated modes lie in the band beside
    the three translational ones; the planar model lacks as many resonances as it has, so
    all three are kept as model discrepancy, no family is asked, and the case is marked
    outside the model class."""
    r, ecc, omega, d = 0.4, 0.15, 0.75, 0.35
    Kx = shear_K(k)
    kt = omega**2 * r**2 * k - k * ecc**2        # kt + k e^2 = Omega^2 r^2 k
    K = np.block([[Kx, ecc * Kx], [ecc * Kx, shear_K(kt + k * ecc**2)]])
    M = np.diag(np.concatenate([m, m * r**2]))
    w = np.sqrt(eigh(K, M, eigvals_only=True))
    a1 = 2 * 0.015 / (w[0] + w[-1])
    C = a1 * w[0] * w[-1] * M + a1 * K
    S = np.hstack([np.eye(3), d * np.eye(3)])
    H = np.array([-(2 * np.pi * f)**2 * (S @ np.linalg.solve(
        K - (2 * np.pi * f)**2 * M + 2j * np.pi * f * C, np.eye(6)[0])) for f in F]).T
    rng = np.random.default_rng(11)
    H *= 1 + 0.005 * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape))
    (case, points, base), log = _diagnose_to_discrepancy(tmp_path, H)
    assert case.outside_class, log
    # the kept terms are the torsion-dominated modes: each within 2 % of an eigenfrequency
    # of the eccentric frame that is not a planar-model mode
    f_true = w / (2 * np.pi)
    assert len(case.discrepancy) == 3, log
    for md in case.discrepancy:
        assert np.min(np.abs(f_true / md.f0 - 1)) < 0.02, (md.f0, f_true)
    assert not any("explains it" in str(line) for line in log), log
