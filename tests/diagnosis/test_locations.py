"""Locations of added physics on an FE model: its levels (mass-carrying nodes at one
elevation), named by node tags, and the families at them on the sparse backend against a
numpy solve of the matrices built by hand from the node rows (and the dense backend)."""

import math

import numpy as np
import scipy.sparse as sp

from nlp.diagnosis.families import (AddedMass, LocalDamper, NonadjacentCoupling,
                                    SecondaryOscillator, extend_parameters)
from nlp.diagnosis.locations import fe_references, floor_name, floors
from nlp.model.damping import RayleighDamping
from nlp.model.nominal import StructuralModel
from nlp.model.parameters import Parameter, ParameterSet
from nlp.solve.problem import Channel, SolverConfig, Target, UpdatingProblem

LEVELS, COLS = 3, 2
NODE_MASS = [[500.0, 700.0], [400.0, 600.0], [300.0, 350.0]]


def _tag(lev, col):
    return 10 * (lev + 1) + col


def _springs(K, row, ground_ux):
    """Add the frame's springs to K: in ux between levels and from level 1 to ``ground_ux``
    (a row, or None: the ground), in uy (stiff) between levels and to the ground, and beams
    joining a level's two nodes."""
    def spring(a, b, k):
        for i, si in ((a, 1), (b, -1)):
            for j, sj in ((a, 1), (b, -1)):
                if i is not None and j is not None:
                    K[i, j] += si * sj * k

    for lv in range(LEVELS):
        for c in range(COLS):
            below = row[(_tag(lv - 1, c), 1)] if lv else ground_ux
            spring(row[(_tag(lv, c), 1)], below, 2.0e5 * (1 + 0.1 * c))
            spring(row[(_tag(lv, c), 2)], row[(_tag(lv - 1, c), 2)] if lv else None, 5.0e6)
        spring(row[(_tag(lv, 0), 1)], row[(_tag(lv, 1), 1)], 8.0e5)
    return K


def _frame():
    """Two columns of nodes, 3 levels, DOFs ux (1) and uy (2) per node, listed level by level
    with uy first (so the ux rows are not every other row from 0); springs in ux between
    levels and to the ground, beams joining a level's two nodes, stiff uy springs."""
    dofs = [(_tag(lv, c), d) for lv in range(LEVELS) for c in range(COLS) for d in (2, 1)]
    n = len(dofs)
    row = {nd: i for i, nd in enumerate(dofs)}
    K = _springs(np.zeros((n, n)), row, None)
    masses = np.array([NODE_MASS[nd // 10 - 1][nd % 10] for nd, _ in dofs])
    coords = tuple((_tag(lv, c), (6.0 * c, 3.0 * (lv + 1))) for lv in range(LEVELS)
                   for c in range(COLS))
    model = StructuralModel(M0=sp.csc_matrix(np.diag(masses)), K0=sp.csc_matrix(K),
                            M_infl=(), K_infl=(sp.csc_matrix(K),), beta_names=(),
                            alpha_names=("k",), beta_nominal=np.ones(0), alpha_nominal=np.ones(1),
                            dofs=tuple(dofs), ndm=2, node_coords=coords)
    r = np.array([1.0 if d == 1 else 0.0 for _, d in dofs])
    return model, row, r


def test_levels_are_node_groups_at_one_elevation():
    model, row, r = _frame()
    fl = floors(model, r)
    assert [f.nodes for f in fl] == [(10, 11), (20, 21), (30, 31)]
    assert [f.rows for f in fl] == [(row[(10, 1)], row[(11, 1)]), (row[(20, 1)], row[(21, 1)]),
                                    (row[(30, 1)], row[(31, 1)])]
    assert floor_name(model, r, 2) == "level at 6 m (nodes 20, 21)"
    refs = fe_references(model, RayleighDamping(0.1, 0.001), r)
    assert np.isclose(refs["m_ref"], np.mean([sum(m) for m in NODE_MASS]))
    np.testing.assert_allclose(refs["floors"][1][[row[(20, 1)], row[(21, 1)]]], [0.5, 0.5])


def test_families_at_levels_on_the_sparse_backend():
    """dm spread over a level's nodes, a spring between two levels' mean ux, an appendage on a
    level's mean ux: the FRF against (K - w^2 M + j w C) q = -M r by numpy."""
    model, row, r = _frame()
    damping = RayleighDamping(0.2, 0.0005)
    refs = fe_references(model, damping, r)
    fams = [AddedMass(2), NonadjacentCoupling(1, 3), SecondaryOscillator(3, 4.0), LocalDamper(1, 0)]
    dm, kc, (mu, fs, zeta), cd = 120.0, 3.0e4, (0.03, 3.5, 0.05), 800.0
    ps = (Parameter("k", "stiffness", 0.0, -0.5, 1.0),
          Parameter("a0", "damping", 1.0, 0.0, 30.0), Parameter("a1", "damping", 1.0, 0.0, 30.0))
    params = extend_parameters(ParameterSet(ps, 1, 0), fams, refs,
                               [[dm], [kc], [mu, fs, zeta], [cd]])
    w = np.linspace(5.0, 80.0, 25)
    chans = tuple(Channel(f"a{nd}", row[(nd, 1)], "absolute_accelerance") for nd in (10, 21, 31))
    tg = Target(w, np.ones((3, w.size), complex), np.ones((3, w.size)), chans, "ground", None,
                ground_r=r)
    pr = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                         enrichments=fams, refs=refs, frf_backend="sparse")
    H = pr.channel_frfs(pr.z0, w)

    n = model.n
    M = np.pad(model.M0.toarray(), (0, 1))
    K = np.pad(model.K0.toarray(), (0, 1))
    C = 0.2 * M + 0.0005 * K
    C[n, n] = 0.0
    for nd in (20, 21):
        M[row[(nd, 1)], row[(nd, 1)]] += dm / 2
    v = np.zeros(n + 1)
    v[[row[(10, 1)], row[(11, 1)]]] = 0.5
    C += cd * np.outer(v, v)
    v[[row[(30, 1)], row[(31, 1)]]] = -0.5
    K += kc * np.outer(v, v)
    u = np.zeros(n + 1)
    u[[row[(30, 1)], row[(31, 1)]]] = 0.5
    u[n] = -1.0
    ms = mu * refs["m_ref"]
    ws = 2 * math.pi * fs
    M[n, n] = ms
    K += ms * ws ** 2 * np.outer(u, u)
    C += 2 * zeta * ms * ws * np.outer(u, u)
    b = -M @ np.append(r, 1.0)
    q = np.array([np.linalg.solve(K - x ** 2 * M + 1j * x * C, b) for x in w]).T
    ref = -(w ** 2) * q[[row[(10, 1)], row[(21, 1)], row[(31, 1)]]] + 1
    np.testing.assert_allclose(H, ref, rtol=1e-9)
    dense = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                            enrichments=fams, refs=refs, frf_backend="dense")
    np.testing.assert_allclose(dense.channel_frfs(dense.z0, w), ref, rtol=1e-9)


def test_an_added_mass_acts_in_every_direction_of_its_nodes():
    """dm at a level is shared by its nodes in ux and uy, as a mass lumped at them: on a
    frame whose ux and uy couple (inclined springs at level 2, as overturning couples a
    frame's sway and its columns' stretch), the FRF equals numpy's with dm/2 added to both
    DOFs of nodes 20 and 21, and differs by over 1 % from one with dm in ux alone."""
    from dataclasses import replace
    model, row, r = _frame()
    K = model.K0.toarray()
    for nd in (20, 21):   # springs at 45 degrees from the level-2 nodes to the ground
        v = np.zeros(model.n)
        v[[row[(nd, 1)], row[(nd, 2)]]] = math.sqrt(0.5)
        K += 3.0e5 * np.outer(v, v)
    model = replace(model, K0=sp.csc_matrix(K), K_infl=(sp.csc_matrix(K),))
    damping = RayleighDamping(0.2, 0.0005)
    refs = fe_references(model, damping, r)
    dm = 400.0
    ps = (Parameter("k", "stiffness", 0.0, -0.5, 1.0),
          Parameter("a0", "damping", 1.0, 0.0, 30.0), Parameter("a1", "damping", 1.0, 0.0, 30.0))
    params = extend_parameters(ParameterSet(ps, 1, 0), [AddedMass(2)], refs, [[dm]])
    w = np.linspace(5.0, 80.0, 25)
    chans = tuple(Channel(f"a{nd}", row[(nd, 1)], "absolute_accelerance") for nd in (10, 21, 31))
    tg = Target(w, np.ones((3, w.size), complex), np.ones((3, w.size)), chans, "ground", None,
                ground_r=r)

    def numpy_frf(dirs):
        M = model.M0.toarray()
        C = 0.2 * M + 0.0005 * K   # the nominal model's law: the added mass brings no dashpot
        for nd in (20, 21):
            for d in dirs:
                M[row[(nd, d)], row[(nd, d)]] += dm / 2
        q = np.array([np.linalg.solve(K - x ** 2 * M + 1j * x * C, -M @ r) for x in w]).T
        return -(w ** 2) * q[[row[(10, 1)], row[(21, 1)], row[(31, 1)]]] + 1
    want = numpy_frf((1, 2))
    for backend in ("sparse", "dense"):
        pr = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                             enrichments=[AddedMass(2)], refs=refs, frf_backend=backend)
        np.testing.assert_allclose(pr.channel_frfs(pr.z0, w), want, rtol=1e-9)
    assert np.abs(want / numpy_frf((1,)) - 1).max() > 0.01


def test_findings_name_fe_locations_in_model_terms():
    from types import SimpleNamespace
    from nlp.diagnosis.families import HystereticDamping
    from nlp.diagnosis.locations import located
    from nlp.diagnosis.units import place
    from nlp.model.nominal import shear_frame
    model, row, r = _frame()
    case = SimpleNamespace(model=model, target=SimpleNamespace(ground_r=r))
    assert place(located(case, AddedMass(2))) == "at level at 6 m (nodes 20, 21)"
    assert place(located(case, LocalDamper(1, 0))) == \
        "between the supports and level at 3 m (nodes 10, 11)"
    assert place(located(case, HystereticDamping(1))) == "in stiffness group k"
    shear = SimpleNamespace(model=shear_frame([1.0, 1.0], [1.0, 1.0]), target=SimpleNamespace())
    assert located(shear, AddedMass(2)) == {"floor": 2}
    assert place(located(shear, AddedMass(2))) == "at floor 2"


def test_without_coordinates_the_channels_are_the_locations():
    """A matrix export has no node coordinates: each channel's DOF with mass is a location."""
    from dataclasses import replace
    model, row, r = _frame()
    bare = replace(model, node_coords=())
    fl = floors(bare, r, (row[(21, 1)], row[(10, 1)], row[(21, 1)]))
    assert [f.rows for f in fl] == [(row[(21, 1)],), (row[(10, 1)],)]
    assert fl[0].name == "node 21 (ux)"


def test_flexible_supports_reroute_the_ground_springs_through_a_base():
    """A flexible base on an FE model (sparse terms) against the frame rebuilt by hand with
    its ux ground springs attached to a base DOF u_b, itself on a spring k_b and dashpot c_b
    to the ground (the uy springs stay on the ground: the base sways in x only), the Rayleigh
    law C = a0 M + a1 K over the rebuilt structure with its base (as an FE program assembles
    it) plus c_b, relative coordinates, q = Z^-1 (-M r)."""
    from nlp.diagnosis.families import BaseFlexibility
    from nlp.diagnosis.locations import located
    from nlp.diagnosis.units import place
    from types import SimpleNamespace
    model, row, r = _frame()
    damping = RayleighDamping(0.3, 0.0005)
    refs = fe_references(model, damping, r)
    np.testing.assert_array_equal(refs["r"], r)
    m_b, k_b, c_b = 900.0, 6.0e5, 1500.0
    ps = (Parameter("k", "stiffness", 0.0, -0.5, 1.0),
          Parameter("a0", "damping", 1.0, 0.0, 30.0), Parameter("a1", "damping", 1.0, 0.0, 30.0))
    fams = [BaseFlexibility()]
    params = extend_parameters(ParameterSet(ps, 1, 0), fams, refs,
                               [[m_b, math.log10(k_b), c_b]])
    w = np.linspace(5.0, 80.0, 25)
    chans = tuple(Channel(f"a{nd}", row[(nd, 1)], "absolute_accelerance") for nd in (10, 21, 31))
    tg = Target(w, np.ones((3, w.size), complex), np.ones((3, w.size)), chans, "ground", None,
                ground_r=r)
    z = np.asarray(params.z_from_theta(np.array([0.15, 1.0, 1.0, m_b, math.log10(k_b), c_b])))
    pr = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                         enrichments=fams, refs=refs, frf_backend="sparse")
    assert pr.backend == "sparse"
    H = pr.channel_frfs(z, w)

    n = model.n
    b = n   # the base DOF: the ux ground springs end on it
    K = 1.15 * _springs(np.zeros((n + 1, n + 1)), row, b)   # the stiffness group at alpha = 0.15
    M = np.pad(model.M0.toarray(), (0, 1))
    M[b, b] = m_b
    K[b, b] += k_b
    C = 0.3 * M + 0.0005 * K
    C[b, b] += c_b
    load = -M @ np.append(r, 1.0)
    q = np.array([np.linalg.solve(K - x ** 2 * M + 1j * x * C, load) for x in w]).T
    ref = -(w ** 2) * q[[row[(10, 1)], row[(21, 1)], row[(31, 1)]]] + 1
    np.testing.assert_allclose(H, ref, rtol=1e-9)
    rigid = UpdatingProblem(model, damping, ParameterSet(ps, 1, 0), tg, frf_backend="sparse",
                            solver=SolverConfig(compile=False))
    assert np.abs(H / rigid.channel_frfs(z[:3], w) - 1).max() > 0.05   # the base matters here
    dense = UpdatingProblem(model, damping, params, tg, solver=SolverConfig(compile=False),
                            enrichments=fams, refs=refs, frf_backend="dense")
    np.testing.assert_allclose(dense.channel_frfs(z, w), ref, rtol=1e-9)
    case = SimpleNamespace(model=model, target=SimpleNamespace(ground_r=r))
    assert place(located(case, BaseFlexibility())) == "under the supports"


def test_without_coordinates_an_added_mass_acts_on_its_nodes_translations():
    """A matrix export (no coordinates): the DOF numbering tells the translations (six per
    node: ux, uy, uz; three: ux, uy of a planar frame), an added mass located by a channel
    moves its node in each of them (the FRF equals numpy's with dm on ux and uy of node 21,
    on a frame whose ux and uy couple), and two channels of one node are one mass location."""
    from dataclasses import replace
    from types import SimpleNamespace
    from nlp.diagnosis.locations import dof_name, located, mass_floors, translations
    from nlp.diagnosis.units import place
    model, row, r = _frame()
    K = model.K0.toarray()
    v = np.zeros(model.n)
    v[[row[(21, 1)], row[(21, 2)]]] = math.sqrt(0.5)
    K += 3.0e5 * np.outer(v, v)
    bare = replace(model, node_coords=(), ndm=None, K0=sp.csc_matrix(K), K_infl=(sp.csc_matrix(K),))
    six = replace(bare, dofs=tuple((nd, d) for nd in (1, 2) for d in range(1, 7)))
    three = replace(bare, dofs=tuple((nd, d) for nd in (1, 2) for d in range(1, 4)))
    assert (translations(bare), translations(six), translations(three)) == (2, 3, 2)
    assert translations(replace(three, ndm=3)) == 3   # a 3-D truss: ux, uy, uz
    assert [dof_name(six, d) for d in range(1, 7)] == ["ux", "uy", "uz", "rx", "ry", "rz"]
    assert [dof_name(three, d) for d in range(1, 4)] == ["ux", "uy", "rz"]
    chan_rows = (row[(21, 1)], row[(21, 2)], row[(10, 1)])
    fl = floors(bare, r, chan_rows)
    assert mass_floors(bare, fl) == [1, 3]
    case = SimpleNamespace(model=bare, target=SimpleNamespace(
        ground_r=r, channels=[SimpleNamespace(dof=i) for i in chan_rows]))
    assert place(located(case, AddedMass(1))) == "at node 21"
    assert place(located(case, NonadjacentCoupling(1, 3))) == \
        "between node 21 (ux) and node 10 (ux)"
    damping = RayleighDamping(0.2, 0.0005)
    refs = fe_references(bare, damping, r, chan_rows)
    dm = 400.0
    ps = (Parameter("k", "stiffness", 0.0, -0.5, 1.0),
          Parameter("a0", "damping", 1.0, 0.0, 30.0), Parameter("a1", "damping", 1.0, 0.0, 30.0))
    params = extend_parameters(ParameterSet(ps, 1, 0), [AddedMass(1)], refs, [[dm]])
    w = np.linspace(5.0, 80.0, 25)
    out = (row[(10, 1)], row[(21, 1)], row[(31, 1)])
    chans = tuple(Channel(f"c{i}", i, "absolute_accelerance") for i in out)
    tg = Target(w, np.ones((3, w.size), complex), np.ones((3, w.size)), chans, "ground", None,
                ground_r=r)
    M0 = bare.M0.toarray()
    C = 0.2 * M0 + 0.0005 * K

    def numpy_frf(dirs):
        M = M0.copy()
        for d in dirs:
            M[row[(21, d)], row[(21, d)]] += dm
        q = np.array([np.linalg.solve(K - x ** 2 * M + 1j * x * C, -M @ r) for x in w]).T
        return -(w ** 2) * q[list(out)] + 1
    want = numpy_frf((1, 2))
    pr = UpdatingProblem(bare, damping, params, tg, solver=SolverConfig(compile=False),
                         enrichments=[AddedMass(1)], refs=refs, frf_backend="sparse")
    np.testing.assert_allclose(pr.channel_frfs(pr.z0, w), want, rtol=1e-9)
    assert np.abs(want / numpy_frf((1,)) - 1).max() > 0.01


def test_finding_statement_names_the_fe_place_and_a_shear_frame_its_floor():
    """diagnosis.json's sentence uses the model's own place (node tag) when the location has
    one, and the floor number on a shear frame."""
    from nlp.diagnosis.verdict import statement
    base = {"physics": "added_mass", "parameters": {"dm5": 10009.6},
            "uncertainty": {"dm5": 89.4}}
    fe = statement({**base, "location": {"floor": 5, "where": "at node 60604"}})
    assert "at node 60604 (dm5 = 1.001e+04 +- 89)" in fe and "floor" not in fe
    shear = statement({**base, "location": {"floor": 5}})
    assert "at floor 5 (" in shear
