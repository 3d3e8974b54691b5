"""The imported-model cases: their files load, the data agree with an independent solve at the
stated truth, and (slow, once an FRF backend for large models is on main) one run recovers it."""

import importlib.util
import json
import os

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from nlp.case.assemble import assemble
from nlp.case.load import load_case

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "..", "cases")
try:
    import openseespy.opensees  # noqa: F401
    HAVE_OPENSEES = True
except Exception:  # ImportError, or RuntimeError when its shared libraries are missing
    HAVE_OPENSEES = False
HAVE_SPARSE = importlib.util.find_spec("nlp.frf.backends") is not None


def _truth_frf(case, truth, idx):
    """Channel accelerances at the truth by sparse direct solves (independent of nlp.frf.reference);
    absolute (plus the table's 1) under ground input."""
    m, tg = case.model, case.target
    al = np.array(list(truth["alpha"].values()))
    M = sp.csc_matrix(m.M0)
    K = sp.csc_matrix(m.K0) + sum(a * sp.csc_matrix(A) for a, A in zip(al, m.K_infl))
    C = truth["a0"] * M + truth["a1"] * K
    rows = [ch.dof for ch in case.channels]
    if tg.excitation == "ground":
        b = -(M @ tg.ground_r)
    else:
        b = np.zeros(m.n)
        b[tg.force_dof] = 1.0
    out = []
    for w in 2 * np.pi * case.f[idx]:
        lu = spla.splu((K - w**2 * M + 1j * w * C).tocsc(), permc_spec="MMD_AT_PLUS_A")
        h = -(w**2) * lu.solve(b.astype(complex))[rows]
        out.append(h + 1 if tg.excitation == "ground" else h)
    return np.array(out).T


@pytest.mark.skipif(not HAVE_OPENSEES, reason="openseespy not importable")
def test_opensees_frame_case_matches_its_truth():
    path = os.path.join(ROOT, "opensees_frame", "case.yaml")
    case = assemble(load_case(path))
    with open(os.path.join(ROOT, "opensees_frame", "truth.json")) as fh:
        truth = json.load(fh)
    assert case.model.n == 120 and len(case.model.K_infl) == 12
    assert [case.model.dofs[ch.dof] for ch in case.channels] == [(300, 1), (600, 1), (800, 1),
                                                                (1000, 1)]
    assert case.target.ground_r.sum() == 40  # ux of the 40 free nodes
    idx = case.selected[::10]
    Ht = _truth_frf(case, truth, idx)
    ratio = np.log(np.abs(case.H[:, idx] / Ht))
    # the data are the truth with 2 % noise: ln|H| scatter ~ 0.014, nothing systematic
    assert np.std(ratio) < 0.02 and abs(np.mean(ratio)) < 0.005


def test_frame3d_case_loads_sparse_matrices_and_matches_its_truth():
    """The 2,100-DOF case is read from its matrix files alone (no OpenSees), kept sparse."""
    path = os.path.join(ROOT, "frame3d_2100", "case.yaml")
    case = assemble(load_case(path))
    with open(os.path.join(ROOT, "frame3d_2100", "truth.json")) as fh:
        truth = json.load(fh)
    m = case.model
    assert m.n == 2100 and m.is_sparse and len(m.K_infl) == 20 and len(case.channels) == 10
    assert m.dofs[case.target.force_dof] == (100604, 1)
    assert m.dofs[case.channels[-1].dof] == (100604, 2)
    idx = case.selected[[case.selected.size // 2]]  # one frequency: one sparse factorisation
    ratio = np.log(np.abs(case.H[:, idx] / _truth_frf(case, truth, idx)))
    assert np.all(np.abs(ratio) < 0.08)  # 2 % noise: |ln| beyond 4 sigma (0.056) is rare


@pytest.mark.slow
@pytest.mark.skipif(not (HAVE_OPENSEES and HAVE_SPARSE), reason="needs openseespy and the sparse "
                    "FRF backend")
def test_opensees_frame_run_recovers_stiffness_groups(tmp_path):
    """One `frf-nlp run` recovers every element-group stiffness within 2 % (2 % noise)."""
    import subprocess
    import sys
    out = str(tmp_path / "out")
    done = subprocess.run([sys.executable, "-m", "nlp", "run",
                           os.path.join(ROOT, "opensees_frame", "case.yaml"), "--out", out],
                          capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "..")))
    assert done.returncode == 0, done.stderr[-2000:]
    with open(os.path.join(out, "result.json")) as fh:
        res = json.load(fh)
    with open(os.path.join(ROOT, "opensees_frame", "truth.json")) as fh:
        truth = json.load(fh)
    upd = {p["name"]: p["updated"] for p in res["parameters"]}
    for name, a in truth["alpha"].items():  # a group's value is its multiplier 1 + alpha
        assert upd[name] == pytest.approx(1 + a, rel=0.02), name
