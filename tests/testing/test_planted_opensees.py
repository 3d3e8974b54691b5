"""scripts/make_planted_opensees.py: the plant written as OpenSees commands and assembled by
OpenSees equals the same plant as edits of the model's matrices (the matrix route of
make_planted_fe.py, itself tested against hand-written chains)."""

import numpy as np
import pytest
import scipy.sparse as sp

from support.paths import load_script

pytest.importorskip("openseespy.opensees")


# one storey, one bay, 3-D: four columns (a group) and four beams (a group); bases fixed at z = 0
FRAME = """
import openseespy.opensees as ops
ops.wipe()
ops.model("basic", "-ndm", 3, "-ndf", 6)
ops.geomTransf("Linear", 1, 1.0, 0.0, 0.0)
ops.geomTransf("Linear", 2, 0.0, 0.0, 1.0)
xy = [(0.0, 0.0), (6.0, 0.0), (6.0, 5.0), (0.0, 5.0)]
for i, (x, y) in enumerate(xy):
    ops.node(i + 1, x, y, 0.0)
    ops.fix(i + 1, 1, 1, 1, 1, 1, 1)
    ops.node(i + 11, x, y, 3.5)
    ops.mass(i + 11, 2.0e4, 2.0e4, 2.0e4, 50.0, 50.0, 50.0)
groups = {"cols": [], "beams": []}
for i in range(4):
    ops.element("elasticBeamColumn", i + 1, i + 1, i + 11, 0.03, 2.0e11, 7.7e10, 2.0e-5,
                1.2e-3, 1.0e-3, 1)
    groups["cols"].append(i + 1)
    ops.element("elasticBeamColumn", i + 5, i + 11, (i + 1) % 4 + 11, 0.05, 2.0e11, 7.7e10,
                1.0e-5, 5.0e-4, 2.0e-2, 2)
    groups["beams"].append(i + 5)
"""
GROUPS = {"k_cols": "cols", "k_beams": "beams"}


def _load(name):
    needs = ("make_frame3d", "make_planted_fe") if name == "make_planted_opensees" else ()
    return load_script(name, needs)


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    from nlp.io.importers.opensees import assemble_script
    path = tmp_path_factory.mktemp("frame") / "frame.py"
    path.write_text(FRAME)
    return str(path), assemble_script(str(path), GROUPS)


def _planted(mod, script, *args, **kw):
    a = mod.assemble_planted(script, GROUPS, mod.plant_commands(*args, **kw))
    return a, list(a["dofs"])


def test_mass_is_added_on_three_translations(frame):
    mod, fe = _load("make_planted_opensees"), _load("make_planted_fe")
    script, nominal = frame
    a, dofs = _planted(mod, script, "mass", 12, "ux", 3.0e3)
    assert dofs == list(nominal["dofs"])
    M_edit, _ = fe.plant_mass(sp.csc_matrix(nominal["M0"]), dofs, 12, 3.0e3)
    np.testing.assert_allclose(a["M0"], M_edit.toarray(), atol=1e-9)
    np.testing.assert_allclose(a["K0"], nominal["K0"], rtol=1e-12, atol=1e-3)
    assert np.trace(a["M0"]) - np.trace(nominal["M0"]) == pytest.approx(9.0e3)


def test_appendage_is_the_bordered_model(frame):
    """A new node, a spring k_s = m_s (2 pi f_s)^2 to node 13 along uy and the mass m_s."""
    mod, fe = _load("make_planted_opensees"), _load("make_planted_fe")
    script, nominal = frame
    m_s, f_s = 500.0, 2.0
    a, dofs = _planted(mod, script, "appendage", 13, "uy", m_s, hz=f_s)
    old = list(nominal["dofs"])
    new = [i for i, d in enumerate(dofs) if d not in old]
    assert len(new) == 1
    order = [dofs.index(d) for d in old] + new
    K = a["K0"][np.ix_(order, order)]
    M = a["M0"][np.ix_(order, order)]
    Mp, Kp, _, extra = fe.plant_appendage(sp.csc_matrix(nominal["M0"]),
                                          sp.csc_matrix(nominal["K0"]), 0.0, 0.0,
                                          old.index((13, 2)), m_s, f_s, 0.02)
    scale = np.abs(Kp.toarray()).max()
    np.testing.assert_allclose(K, Kp.toarray(), atol=1e-12 * scale)
    np.testing.assert_allclose(M, Mp.toarray(), atol=1e-9)
    # the groups are the model's: the plant's spring is in none of them
    for Kr_a, Kr in zip(a["K_infl"], nominal["K_infl"]):
        np.testing.assert_allclose(Kr_a[np.ix_(order[:-1], order[:-1])], Kr, atol=1e-12 * scale)


def test_support_is_the_rigid_base_up_to_the_ties(frame):
    """Condensing the massless released bases onto the foundation node leaves the matrix
    route's rigid base (make_planted_fe.plant_support) up to the ties' compliance
    (1 / TIE_RATIO); without the ties' stiffness the base would not follow."""
    mod, fe = _load("make_planted_opensees"), _load("make_planted_fe")
    script, nominal = frame
    m_b, k_b = 3.0e4, 1.0e8
    a, dofs = _planted(mod, script, "support", None, "ux", m_b, kb=k_b)
    old = list(nominal["dofs"])
    new = [i for i, d in enumerate(dofs) if d not in old]
    bases = [i for i in new if dofs[i][0] <= 4]          # the released column bases
    (found,) = [i for i in new if dofs[i][0] > 4]          # the foundation node
    assert len(bases) == 4 and all(dofs[i][1] == 1 for i in bases)
    keep = [dofs.index(d) for d in old] + [found]
    K = a["K0"]
    Kc = K[np.ix_(keep, keep)] - K[np.ix_(keep, bases)] @ np.linalg.solve(
        K[np.ix_(bases, bases)], K[np.ix_(bases, keep)])
    assert np.abs(a["M0"][np.ix_(bases, bases)]).max() == 0.0
    Mp, Kp, _ = fe.plant_support(sp.csc_matrix(nominal["M0"]), sp.csc_matrix(nominal["K0"]),
                                 old, "ux", m_b, k_b)
    np.testing.assert_allclose(a["M0"][np.ix_(keep, keep)], Mp.toarray(), atol=1e-9)
    err = np.abs(Kc - Kp.toarray()).max() / np.abs(Kp.toarray()).max()
    assert 1e-9 < err < 10.0 / mod.TIE_RATIO
