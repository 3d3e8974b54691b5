"""A level dependence within what joints do is not a finding (nlp.diagnosis.materiality),
on FRFs of a 3-storey frame computed here with numpy."""

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from nlp.diagnosis.levels import _own_chi2, _phi, level_fit, shared_stiffness
from nlp.diagnosis.materiality import JOINT_CHANGE, band, banded_change
from support.diagnosis import F, frame_matrices, write_case_yaml, write_frf
from support.frames import shear_K


def test_the_band_is_relative_to_the_other_levels_stiffness():
    """theta = 0.1 is a stiffness 1.1 k_nominal; +-3 % of it is 1.067-1.133 k_nominal
    (Eqn 23), cut at the parameter's own bounds."""
    p = SimpleNamespace(lower=-0.5, upper=1.0)
    lo, hi = band(0.1, p, 0.03)
    assert lo == pytest.approx(1.1 * 0.97 - 1) and hi == pytest.approx(1.1 * 1.03 - 1)
    lo, hi = band(0.1, SimpleNamespace(lower=-0.5, upper=0.12), 0.03)
    assert hi == 0.12 and lo == pytest.approx(1.1 * 0.97 - 1)


def _accelerance(M, C, K, rng, noise):
    """Accelerances of every floor to a force at floor 1, with complex noise."""
    b = np.zeros(M.shape[0])
    b[0] = 1.0
    H = np.array([-(2 * np.pi * f) ** 2 * np.linalg.solve(
        K - (2 * np.pi * f) ** 2 * M + 2j * np.pi * f * C, b) for f in F]).T
    return H * (1 + noise * (rng.standard_normal(H.shape) + 1j * rng.standard_normal(H.shape)))


@pytest.mark.slow  # three level fits, two shared-set comparisons and four banded refits: ~40 s
def test_joint_sized_changes_are_level_dependent_but_not_material(tmp_path):
    """The second level differs from the first by story stiffness changes of -2, +1.5 and
    -2.5 % (every story, both signs: joints) or by +8 % at story 2 alone (an element). At
    0.2 % noise both are level-dependent (one common set misses by more than BIC's price),
    but only the element lies outside what changes of at most JOINT_CHANGE in each story
    stiffness and floor mass explain (a mass within 3 % and a stiffness within 3 % cannot
    make a story 8 % stiffer without moving the other modes); the joints' banded rise is
    that of a model containing the truth, a chi-square of a few degrees of freedom, far
    under the price."""
    rng = np.random.default_rng(3)
    m, k = np.array([5.0, 5.0, 5.0]), np.array([3000.0, 2800.0, 2600.0])
    M, C, K = frame_matrices(m, k, zeta=0.015)
    write_frf(tmp_path, "lo.npz", _accelerance(M, C, K, rng, 0.002))
    others = {"joints": shear_K(k * [0.98, 1.015, 0.975]), "element": shear_K(k * [1.0, 1.08, 1.0])}
    cfg = write_case_yaml(tmp_path, m, k, [("lo.npz", 1)], {"fixed": {"m1": 5.0}},
                          {"model": "general", "zeta": 0.015})
    cfg = replace(cfg, solver=replace(cfg.solver, options={"max_iter": 3000}))
    ref = level_fit(cfg, cfg.data.file)
    assert JOINT_CHANGE == pytest.approx(0.03)   # the sizes above straddle it
    material = {}
    for name, Ko in others.items():
        write_frf(tmp_path, f"{name}.npz", _accelerance(M, C, Ko, rng, 0.002))
        lv = level_fit(cfg, str(tmp_path / f"{name}.npz"), ref["z"])
        lr = shared_stiffness(ref, lv)
        assert lr["converged"] and lr["excess"] > lr["limit"], (name, lr["excess"], lr["limit"])
        out = banded_change(ref, lv, lr["limit"], {"ref": _own_chi2(ref), "lv": _own_chi2(lv)},
                            {"ref": _phi(ref), "lv": _phi(lv)})
        material[name] = out["material"]
        if name == "joints":
            assert out["excess"] < 0.5 * out["limit"], out
        else:
            assert out["excess"] > 5 * out["limit"], out
    assert material == {"joints": False, "element": True}


def test_a_level_dependence_within_the_band_is_said_not_found():
    """The verdict's statements say it only when the comparison found no material change,
    and say so differently when the banded refit could not decide."""
    from nlp.diagnosis.verdict import _joint_statements
    within = {"joint_band": {"delta": 0.03, "material": False, "within": True}}
    open_ = {"joint_band": {"delta": 0.03, "material": False, "within": False}}
    assert "explain" in _joint_statements(within, False)[0]
    assert "not decided" in _joint_statements(open_, False)[0]
    material = {"joint_band": {"delta": 0.03, "material": True, "within": False}}
    assert _joint_statements(material, False) == []
    assert _joint_statements(within, True) == [] and _joint_statements(None, False) == []


def test_within_the_band_only_falling_damping_is_a_finding(monkeypatch):
    """The gate's logic: material -> a finding; within the band -> a finding only when the
    level kind is damping that falls as the level rises (dry friction); rising damping, a
    stiffness or a mass, or an unknown order -> none."""
    import nlp.diagnosis.materiality as mat
    ref = {"case": None}
    monkeypatch.setattr(mat, "applies", lambda ref: True)
    monkeypatch.setattr(mat, "level_order", lambda ref, lv: 1)
    cases = [(True, None, True), (False, ("damping", False), True), (False, ("damping", True), False),
             (False, ("damping", None), False), (False, ("stiffness", False), False),
             (False, ("mass", False), False)]
    for material, kind, expected in cases:
        monkeypatch.setattr(mat, "banded_change", lambda *a, m=material: {
            "delta": 0.03, "excess": 100.0 if m else 0.0, "limit": 50.0, "material": m,
            "within": not m})
        monkeypatch.setattr(mat, "level_kind", lambda *a, k=kind: {"kind": k[0], "rises": k[1]})
        out, _ = mat.joint_gate(ref, ref, 50.0, {}, {"ref": 1.0, "lv": 1.0}, lambda m: None)
        assert out["finding"] is expected, (material, kind)
