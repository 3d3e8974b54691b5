"""Models from an OpenSeesPy script: M, K and element-group influence matrices.

The user's script builds the model with ``openseespy.opensees`` (nodes,
``fix``, masses, elements) and no analysis. It may define a dict ``groups``
mapping a name ("columns_story3", "beams", "support_springs") to a list of
element tags, or to ``{"elements": [...], "nodes": [...]}`` for mass groups.
The case names its updating parameters by such groups, or by explicit tags.

Assembly (why this way: OpenSees assembles real element libraries better than
code we would write): the system ``FullGeneral`` with the ``GimmeMCK``
integrator makes the analysis form the matrix m M + c C + k K, which
``printA('-ret')`` returns; (1, 0, 0) gives M and (0, 0, 1) gives K with the
fixed DOFs removed (``constraints('Plain')``). The influence matrix of a
stiffness group is K assembled from that group's elements alone (the script
is re-run and the other elements removed), so K = K0 + sum_r alpha_r K0_r
(Eqn 23); a mass group's M0_r holds its elements' mass and its nodes' nodal
masses (Eqn 24). The row of each equation is read back with ``nodeDOFs``.
"""

import contextlib
import os
import runpy
import sys
import tempfile

import numpy as np
import scipy.sparse as sp

from nlp.errors import InputError
from nlp.model.nominal import StructuralModel
from nlp.io.importers.matrices import check_mass

__all__ = ["assemble_script", "load_opensees"]


def _ops(case_path):
    try:
        import openseespy.opensees as ops
    except Exception as exc:  # not installed, or its shared libraries are missing
        raise InputError(case_path, "model.type", "openseespy importable for model.type "
                         f"opensees (pip install 'frf-nlp[opensees]'; {exc})") from None
    return ops


@contextlib.contextmanager
def _quiet():
    """Silence what the script prints (the model is built again for every group)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = os.dup(1), os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def _run_script(ops, script, log):
    """Wipe OpenSees, run the script; returns its globals. OpenSees's own messages go
    to the log file (``logFile -noEcho``): assembling M alone makes it warn that the
    system is singular, which is expected; on failure its last message is quoted."""
    ops.wipe()
    ops.logFile(log, "-noEcho")
    try:
        with _quiet():
            return runpy.run_path(script, run_name="__frf_nlp__")
    except Exception as exc:
        with open(log, errors="replace") as fh:
            said = [ln.strip() for ln in fh if ln.strip()]
        raise InputError(script, "<script>", f"an OpenSeesPy script that builds the model "
                         f"({type(exc).__name__}: {exc}"
                         f"{'; OpenSees: ' + said[-1] if said else ''})") from None


def _matrix(ops, m, k):
    """m M + k K as assembled by OpenSees (dense, free DOFs) and the equation map."""
    ops.wipeAnalysis()
    ops.system("FullGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    ops.integrator("GimmeMCK", float(m), 0.0, float(k))
    ops.algorithm("Linear")
    ops.analysis("Transient")
    ops.analyze(1, 0.0)  # forms the matrix; the solve may fail (singular M): irrelevant
    A = np.asarray(ops.printA("-ret"), dtype=float)
    n = int(round(np.sqrt(A.size)))
    dofs = [None] * n
    ndf = {}
    for node in ops.getNodeTags():
        eqs = ops.nodeDOFs(node)
        ndf[int(node)] = len(eqs)
        for j, eq in enumerate(eqs):
            if 0 <= eq < n:
                dofs[eq] = (int(node), j + 1)
    ops.wipeAnalysis()
    return A.reshape(n, n), tuple(dofs), ndf


def _group_members(spec, script_groups, key, case_path, kind):
    """(elements, nodes) of a group spec: a script group name, a tag list or {elements, nodes}."""
    if isinstance(spec, str):
        if spec not in script_groups:
            raise InputError(case_path, key, "the name of a group in the script's `groups` dict "
                             f"({sorted(script_groups) or 'the script defines none'}) or a list "
                             "of element tags", spec)
        spec = script_groups[spec]
    if isinstance(spec, dict):
        elements, nodes = list(spec.get("elements", ())), list(spec.get("nodes", ()))
    else:
        elements, nodes = list(spec), []
    if kind == "stiffness" and nodes:
        raise InputError(case_path, key, "element tags only (a stiffness group has no nodes)", spec)
    if not elements and not nodes:
        raise InputError(case_path, key, "a non-empty group", spec)
    return [int(e) for e in elements], [int(nd) for nd in nodes]


def assemble_script(script, stiffness_groups=None, mass_groups=None, case_path=None):
    """Assemble an OpenSeesPy script's model.

    Parameters
    ----------
    script : str
        Path of the model script.
    stiffness_groups, mass_groups : dict name -> group spec
        A spec is the name of an entry in the script's ``groups`` dict, a list
        of element tags, or ``{"elements": [...], "nodes": [...]}``.
    case_path : str
        File named in input errors (the case), default the script.

    Returns
    -------
    dict with M0, K0 (dense ndarray, N/m and kg in the script's units), K_infl
    and M_infl (lists in the order of the dicts), dofs ((node, dof) per row),
    ndm and ndf of the nodes.
    """
    case_path = case_path or script
    ops = _ops(case_path)
    with tempfile.TemporaryDirectory() as tmp:
        return _assemble(ops, script, stiffness_groups, mass_groups, case_path,
                         os.path.join(tmp, "opensees.log"))


def _assemble(ops, script, stiffness_groups, mass_groups, case_path, log):
    env = _run_script(ops, script, log)
    script_groups = env.get("groups") or {}
    all_elements = [int(e) for e in ops.getEleTags()]
    all_nodes = [int(n) for n in ops.getNodeTags()]
    if not all_nodes:
        raise InputError(script, "<script>", "a script that defines nodes and elements")
    ndm = len(ops.nodeCoord(all_nodes[0]))
    K0, dofs, node_ndf = _matrix(ops, 0, 1)
    M0, dofs_m, _ = _matrix(ops, 1, 0)
    ndf = max(node_ndf.values())
    members = {}
    seen = {}
    for section, groups, kind in (("stiffness_groups", stiffness_groups or {}, "stiffness"),
                                  ("mass_groups", mass_groups or {}, "mass")):
        for name, spec in groups.items():
            key = f"model.{section}.{name}"
            els, nodes = _group_members(spec, script_groups, key, case_path, kind)
            for e in els:
                if e not in all_elements:
                    raise InputError(case_path, key, "element tags of the model", e)
                if kind == "stiffness":
                    if e in seen:
                        raise InputError(case_path, key, f"each element in one stiffness group "
                                         f"(element {e} is also in {seen[e]})", e)
                    seen[e] = name
            for nd in nodes:
                if nd not in all_nodes:
                    raise InputError(case_path, key, "node tags of the model", nd)
            members[(kind, name)] = (els, nodes)
    infl = {}
    for (kind, name), (els, nodes) in members.items():
        _run_script(ops, script, log)
        keep = set(els)
        for e in all_elements:
            if e not in keep:
                ops.remove("element", e)
        if kind == "mass":
            keep_nodes = set(nodes)
            for nd in all_nodes:
                if nd not in keep_nodes:
                    ops.mass(nd, *([0.0] * node_ndf[nd]))
        A, d, _ = _matrix(ops, 0, 1) if kind == "stiffness" else _matrix(ops, 1, 0)
        if d != dofs:
            raise InputError(case_path, f"model.{kind}_groups.{name}", "a group whose removal "
                             "keeps the model's DOF numbering (OpenSees renumbered the DOFs)")
        infl[(kind, name)] = A
    coords = tuple((nd, tuple(float(x) for x in ops.nodeCoord(nd))) for nd in all_nodes)
    ops.wipe()
    if dofs_m != dofs or any(d is None for d in dofs):
        raise InputError(script, "<script>", "a model whose DOFs OpenSees numbers consistently")
    return {"M0": M0, "K0": K0, "dofs": dofs, "ndm": ndm, "ndf": ndf, "coords": coords,
            "K_infl": [infl[("stiffness", n)] for n in (stiffness_groups or {})],
            "M_infl": [infl[("mass", n)] for n in (mass_groups or {})]}


def load_opensees(cfg, case_path):
    """StructuralModel (sparse matrices) of a case's ``model: {type: opensees, script, ...}``."""
    a = assemble_script(cfg.script, cfg.stiffness_groups, cfg.mass_groups, case_path)
    check_mass(a["M0"], cfg.script, "<mass matrix>")

    def csc(A):
        A = 0.5 * (A + A.T)  # OpenSees's assembly is symmetric to round-off
        return sp.csc_matrix(np.where(np.abs(A) > 1e-14 * np.abs(A).max(initial=0.0), A, 0.0))

    names_k, names_m = tuple(cfg.stiffness_groups), tuple(cfg.mass_groups)
    return StructuralModel(
        M0=csc(a["M0"]), K0=csc(a["K0"]),
        M_infl=tuple(csc(A) for A in a["M_infl"]), K_infl=tuple(csc(A) for A in a["K_infl"]),
        beta_names=names_m, alpha_names=names_k,
        beta_nominal=np.ones(len(names_m)), alpha_nominal=np.ones(len(names_k)),
        dof_names=tuple(f"{nd}.{d}" for nd, d in a["dofs"]), dofs=a["dofs"], ndm=a["ndm"],
        node_coords=a["coords"])
