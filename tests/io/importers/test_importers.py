"""Model import: OpenSees scripts and matrix files checked against hand-derived matrices;
sensors and forces at a node and DOF; bad input named by file and key."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
import yaml

from nlp.case.assemble import assemble
from nlp.case.load import load_case
from nlp.errors import InputError
from support.frames import random_system

try:  # openseespy is an optional extra; its wheel needs libblas/liblapack
    import openseespy.opensees  # noqa: F401
    HAVE_OPENSEES = True
except Exception:  # ImportError, or RuntimeError when its shared libraries are missing
    HAVE_OPENSEES = False
needs_opensees = pytest.mark.skipif(not HAVE_OPENSEES, reason="openseespy not importable")

E = 2.0e11


def beam_element(A, I, x1, y1, x2, y2, rho=0.0):
    """Euler-Bernoulli 2-D frame element in global coordinates (written from the textbook,
    independently of the package): stiffness (EA/L; 12EI/L^3, 6EI/L^2, 4EI/L, 2EI/L) and
    the consistent mass (rho L / 420 [156, 22L, 54, -13L; ...], axial rho L / 6 [2, 1; 1, 2])."""
    L = np.hypot(x2 - x1, y2 - y1)
    c, s = (x2 - x1) / L, (y2 - y1) / L
    a, b1, b2, b3, b4 = E * A / L, 12 * E * I / L**3, 6 * E * I / L**2, 4 * E * I / L, 2 * E * I / L
    k = np.array([[a, 0, 0, -a, 0, 0],
                  [0, b1, b2, 0, -b1, b2],
                  [0, b2, b3, 0, -b2, b4],
                  [-a, 0, 0, a, 0, 0],
                  [0, -b1, -b2, 0, b1, -b2],
                  [0, b2, b4, 0, -b2, b3]])
    m = rho * L / 420 * np.array([[140, 0, 0, 70, 0, 0],
                                  [0, 156, 22 * L, 0, 54, -13 * L],
                                  [0, 22 * L, 4 * L**2, 0, 13 * L, -3 * L**2],
                                  [70, 0, 0, 140, 0, 0],
                                  [0, 54, 13 * L, 0, 156, -22 * L],
                                  [0, -13 * L, -3 * L**2, 0, -22 * L, 4 * L**2]])
    R = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])
    T = np.kron(np.eye(2), R)
    return T.T @ k @ T, T.T @ m @ T


PORTAL = """
import openseespy.opensees as ops
ops.model("basic", "-ndm", 2, "-ndf", 3)
for tag, x, y in ((1, 0.0, 0.0), (2, 5.0, 0.0), (3, 0.0, 3.0), (4, 5.0, 3.0)):
    ops.node(tag, x, y)
ops.fix(1, 1, 1, 1)
ops.fix(2, 1, 1, 1)
ops.mass(3, 1000.0, 1000.0, 10.0)
ops.mass(4, 1000.0, 1000.0, 10.0)
ops.geomTransf("Linear", 1)
ops.element("elasticBeamColumn", 1, 1, 3, 0.01, 2.0e11, 1.0e-4, 1)
ops.element("elasticBeamColumn", 2, 2, 4, 0.01, 2.0e11, 1.0e-4, 1)
ops.element("elasticBeamColumn", 3, 3, 4, 0.008, 2.0e11, 2.0e-4, 1, "-mass", 50.0, "-cMass")
groups = {"columns": [1, 2], "beams": [3]}
"""


def _portal_by_hand():
    """Free DOFs (3: ux, uy, rz), (4: ux, uy, rz) of the portal frame, assembled by hand."""
    index = {3: slice(0, 3), 4: slice(3, 6)}
    K = {"columns": np.zeros((6, 6)), "beams": np.zeros((6, 6))}
    M = np.diag([1000.0, 1000.0, 10.0] * 2)
    Mb = np.zeros((6, 6))
    for group, A, I, (n1, xy1), (n2, xy2), rho in (
            ("columns", 0.01, 1e-4, (1, (0, 0)), (3, (0, 3)), 0.0),
            ("columns", 0.01, 1e-4, (2, (5, 0)), (4, (5, 3)), 0.0),
            ("beams", 0.008, 2e-4, (3, (0, 3)), (4, (5, 3)), 50.0)):
        ke, me = beam_element(A, I, *xy1, *xy2, rho=rho)
        for a, na in ((slice(0, 3), n1), (slice(3, 6), n2)):
            for b, nb in ((slice(0, 3), n1), (slice(3, 6), n2)):
                if na in index and nb in index:
                    K[group][index[na], index[nb]] += ke[a, b]
                    Mb[index[na], index[nb]] += me[a, b]
    return K, M + Mb, Mb


@needs_opensees
def test_opensees_cantilever_matches_euler_bernoulli(tmp_path):
    from nlp.io.importers.opensees import assemble_script
    script = tmp_path / "cantilever.py"
    script.write_text(textwrap.dedent("""
        import openseespy.opensees as ops
        ops.model("basic", "-ndm", 2, "-ndf", 3)
        ops.node(1, 0.0, 0.0)
        ops.node(2, 0.0, 3.0)
        ops.fix(1, 1, 1, 1)
        ops.mass(2, 10.0, 10.0, 0.5)
        ops.geomTransf("Linear", 1)
        ops.element("elasticBeamColumn", 1, 1, 2, 0.01, 2.0e11, 1.0e-4, 1)
        """))
    a = assemble_script(str(script), {"column": [1]})
    L, EI, EA = 3.0, E * 1e-4, E * 0.01
    # vertical cantilever tip: ux is the bending direction, uy the axial one
    K = np.array([[12 * EI / L**3, 0, 6 * EI / L**2],
                  [0, EA / L, 0],
                  [6 * EI / L**2, 0, 4 * EI / L]])
    assert a["dofs"] == ((2, 1), (2, 2), (2, 3))
    np.testing.assert_allclose(a["K0"], K, rtol=1e-12, atol=1e-6 * EA / L)
    np.testing.assert_allclose(a["K_infl"][0], K, rtol=1e-12, atol=1e-6 * EA / L)
    np.testing.assert_allclose(a["M0"], np.diag([10.0, 10.0, 0.5]), atol=1e-12)
    # tip deflection under a unit lateral load: the textbook L^3 / (3 EI)
    assert np.linalg.solve(a["K0"], [1.0, 0, 0])[0] == pytest.approx(L**3 / (3 * EI), rel=1e-12)


@needs_opensees
def test_opensees_portal_frame_groups_match_hand_assembly(tmp_path):
    from nlp.io.importers.opensees import assemble_script
    script = tmp_path / "portal.py"
    script.write_text(PORTAL)
    a = assemble_script(str(script), {"k_col": "columns", "k_beam": [3]},
                        {"m_roof": {"elements": [3], "nodes": [4]}})
    K, M, Mb = _portal_by_hand()
    scale = np.abs(K["columns"]).max()
    assert a["dofs"] == ((3, 1), (3, 2), (3, 3), (4, 1), (4, 2), (4, 3))
    np.testing.assert_allclose(a["K_infl"][0], K["columns"], atol=1e-9 * scale)
    np.testing.assert_allclose(a["K_infl"][1], K["beams"], atol=1e-9 * scale)
    np.testing.assert_allclose(a["K0"], K["columns"] + K["beams"], atol=1e-9 * scale)
    np.testing.assert_allclose(a["M0"], M, atol=1e-9)
    # the mass group: the beam's consistent mass plus node 4's nodal mass
    np.testing.assert_allclose(a["M_infl"][0], Mb + np.diag([0, 0, 0, 1000.0, 1000.0, 10.0]),
                               atol=1e-9)
    # sway stiffness of the rigid-beam limit is not what we have; check one closed form entry:
    # K[ux3, ux3] = 12 EI_c / h^3 + EA_b / L
    assert a["K0"][0, 0] == pytest.approx(12 * E * 1e-4 / 27 + E * 0.008 / 5, rel=1e-12)


def _frame_case(folder, model, channels, excitation, extra=None):
    """A case file with synthetic data (its values do not matter for assembly)."""
    n_ch = len(channels)
    f = np.linspace(1, 50, 50)
    np.savez(os.path.join(folder, "frf.npz"), f=f, H=np.ones((n_ch, f.size)) * (1 + 1j))
    cfg = {"name": "t", "model": model, "damping": {"model": "rayleigh", "zeta": 0.02},
           "excitation": excitation, "parameters": {},
           "data": {"file": "frf.npz", "window": "none", "channels": [dict(c, column=i, output="receptance")
                                                    for i, c in enumerate(channels)]},
           "frequencies": {"method": "all"}, "search": {"starts": 1}}
    cfg.update(extra or {})
    path = os.path.join(folder, "case.yaml")
    with open(path, "w") as fh:
        yaml.safe_dump(cfg, fh)
    return path


@needs_opensees
def test_opensees_case_sensor_at_node_and_dof_gives_hand_frf(tmp_path):
    """Channels at (node, dof), ground motion along ux: the package's FRF equals an
    independent solve of (K - w^2 M + jwC) q = -M r with r = 1 on the ux DOFs."""
    (tmp_path / "portal.py").write_text(PORTAL)
    path = _frame_case(str(tmp_path), {"type": "opensees", "script": "portal.py",
                                       "stiffness_groups": {"k_col": "columns", "k_beam": "beams"}},
                       [{"name": "roof_x", "node": 4, "dof": "ux"},
                        {"name": "rot3", "node": 3, "dof": 3}], {"type": "ground"})
    case = assemble(load_case(path))
    assert [c.dof for c in case.channels] == [3, 2]
    np.testing.assert_array_equal(case.target.ground_r, [1, 0, 0, 1, 0, 0])
    from nlp.case.assemble import build_problem
    pr = build_problem(case)
    M, K, C = pr.matrices(pr.z0)
    Kh, Mh, _ = _portal_by_hand()
    np.testing.assert_allclose(K, Kh["columns"] + Kh["beams"], atol=1e-6)
    w = 2 * np.pi * np.array([3.0, 11.0])
    r = np.array([1.0, 0, 0, 1, 0, 0])
    Hx = np.array([np.linalg.solve(Kh["columns"] + Kh["beams"] - wk**2 * Mh + 1j * wk * C,
                                   -Mh @ r) for wk in w]).T
    np.testing.assert_allclose(pr.channel_frfs(pr.z0, w), Hx[[3, 2]], rtol=1e-8)


def _full_frame_matrices():
    """A 2-column, 2-node-high frame with its 2 base nodes kept (constrained DOFs included)."""
    nodes = {1: (0, 0), 2: (4, 0), 3: (0, 3), 4: (4, 3)}
    order = [(nd, d) for nd in (1, 2, 3, 4) for d in (1, 2, 3)]
    pos = {k: i for i, k in enumerate(order)}
    K = np.zeros((12, 12))
    Kc = np.zeros((12, 12))
    for (n1, n2, A, I, grp) in ((1, 3, 0.01, 1e-4, "c"), (2, 4, 0.01, 1e-4, "c"),
                                (3, 4, 0.008, 2e-4, "b")):
        ke, _ = beam_element(A, I, *nodes[n1], *nodes[n2])
        idx = [pos[(n1, d)] for d in (1, 2, 3)] + [pos[(n2, d)] for d in (1, 2, 3)]
        K[np.ix_(idx, idx)] += ke
        if grp == "c":
            Kc[np.ix_(idx, idx)] += ke
    M = np.diag([500.0, 500.0, 5.0] * 4)
    return order, M, K, Kc


@pytest.mark.parametrize("ext", ["mtx", "npz", "mat"])
def test_matrix_files_round_trip_with_constrained_dofs_removed(tmp_path, ext):
    order, M, K, Kc = _full_frame_matrices()
    folder = str(tmp_path)
    names = {"ux": 1, "uy": 2, "rz": 3}
    with open(os.path.join(folder, "dofs.csv"), "w") as fh:  # DOFs by name, as exports label them
        fh.write("node,dof\n" + "".join(f"{nd},{['ux', 'uy', 'rz'][d - 1]}\n" for nd, d in order))
    files = {}
    for key, A in (("M", M), ("K", K), ("Kc", Kc)):
        name = f"{key}.{ext}"
        S = sp.csc_matrix(A)
        if ext == "mtx":
            scipy.io.mmwrite(os.path.join(folder, name), S, symmetry="symmetric")
        elif ext == "npz":
            sp.save_npz(os.path.join(folder, name), S)
        else:
            scipy.io.savemat(os.path.join(folder, name), {key: S})
        files[key] = name
    cons = [[nd, d] for nd in (1, 2) for d in ("ux", "uy", "rz")]
    path = _frame_case(folder, {"type": "matrices", "M": files["M"], "K": files["K"],
                                "dof_map": "dofs.csv", "constrained": cons,
                                "stiffness_groups": {"k_col": files["Kc"]}},
                       [{"name": "n4x", "node": 4, "dof": "ux"}], {"type": "force", "node": 3,
                                                                   "dof": names["ux"]})
    case = assemble(load_case(path))
    keep = list(range(6, 12))
    np.testing.assert_allclose(case.model.K0, K[np.ix_(keep, keep)], rtol=1e-12, atol=1e-3)
    np.testing.assert_allclose(case.model.K_infl[0], Kc[np.ix_(keep, keep)], rtol=1e-12, atol=1e-3)
    np.testing.assert_allclose(case.model.M0, M[np.ix_(keep, keep)])
    assert case.model.dofs == tuple(order[6:])
    assert case.channels[0].dof == 3 and case.target.force_dof == 0


def test_bad_imports_name_file_and_key(tmp_path):
    order, M, K, Kc = _full_frame_matrices()
    folder = str(tmp_path)
    for key, A in (("M", M), ("K", K), ("Kc", Kc)):
        scipy.io.mmwrite(os.path.join(folder, f"{key}.mtx"), sp.csc_matrix(A))
    with open(os.path.join(folder, "dofs.csv"), "w") as fh:
        fh.write("node,dof\n" + "".join(f"{nd},{d}\n" for nd, d in order))
    model = {"type": "matrices", "M": "M.mtx", "K": "K.mtx", "dof_map": "dofs.csv",
             "constrained": [[1, 1], [1, 2], [1, 3], [2, 1], [2, 2], [2, 3]],
             "stiffness_groups": {"k_col": "Kc.mtx"}}
    path = _frame_case(folder, model, [{"name": "x", "node": 99, "dof": 1}], {"type": "ground"})
    with pytest.raises(InputError) as e:
        assemble(load_case(path))
    assert e.value.file == path and e.value.key == "data.channels[0].node"
    path = _frame_case(folder, model, [{"name": "x", "node": 1, "dof": 1}], {"type": "ground"})
    with pytest.raises(InputError) as e:  # a fully constrained node is no sensor location
        assemble(load_case(path))
    assert e.value.key == "data.channels[0].node"
    path = _frame_case(folder, model, [{"name": "x", "node": 3, "dof": 5}], {"type": "ground"})
    with pytest.raises(InputError) as e:  # a 2-D frame node has no DOF 5
        assemble(load_case(path))
    assert e.value.key == "data.channels[0].dof"
    path = _frame_case(folder, dict(model, stiffness_groups={"k_col": "nope.mtx"}),
                       [{"name": "x", "node": 3, "dof": 1}], {"type": "ground"})
    with pytest.raises(InputError) as e:
        load_case(path)
    assert e.value.key == "model.stiffness_groups.k_col"
    # from the command line: one line, exit status 2, no traceback
    path = _frame_case(folder, model, [{"name": "x", "node": 99, "dof": 1}], {"type": "ground"})
    out = subprocess.run([sys.executable, "-m", "nlp", "run", path, "--out", str(tmp_path / "o")],
                         capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "data.channels[0].node" in out.stderr + out.stdout


@needs_opensees
def test_opensees_missing_group_names_case_and_key(tmp_path):
    (tmp_path / "portal.py").write_text(PORTAL)
    path = _frame_case(str(tmp_path), {"type": "opensees", "script": "portal.py",
                                       "stiffness_groups": {"k_x": "braces"}},
                       [{"name": "roof_x", "node": 4, "dof": "ux"}], {"type": "ground"})
    with pytest.raises(InputError) as e:
        assemble(load_case(path))
    assert e.value.file == path and e.value.key == "model.stiffness_groups.k_x"
    assert "columns" in str(e.value)


def test_large_model_paths_of_the_numpy_frf_agree_with_the_dense_ones(monkeypatch):
    """The per-frequency sparse solve and the Arnoldi modes used above LARGE_N DOFs give the
    dense results (random non-proportionally damped system, threshold lowered)."""
    import nlp.frf.reference as frf
    rng = np.random.default_rng(7)
    M, C, K = random_system(40, rng)
    w = np.array([0.5, 2.0, 7.0])
    H_dense = frf.frf_dynamic_stiffness(M, C, K, w, "force", 3, "accelerance")
    f_dense, z_dense, _ = frf.modal_parameters(M, C, K)
    monkeypatch.setattr(frf, "LARGE_N", 10)
    monkeypatch.setattr(frf, "N_MODES_LARGE", 5)
    np.testing.assert_allclose(frf.frf_dynamic_stiffness(M, C, K, w, "force", 3, "accelerance"),
                               H_dense, rtol=1e-9)
    f_s, z_s, _ = frf.modal_parameters(sp.csc_matrix(M), sp.csc_matrix(C), sp.csc_matrix(K))
    np.testing.assert_allclose(f_s[:4], f_dense[:4], rtol=1e-8)
    np.testing.assert_allclose(z_s[:4], z_dense[:4], rtol=1e-6)
