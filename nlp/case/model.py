"""The case's structural model and where its sensors and input sit: the nominal model of the
model section, and the row (DOF) of a floor, or of a node and DOF, of that model."""


from nlp.case.checks import check_model_matrices
from nlp.errors import InputError
from nlp.frf.reference import BASE_DOF
from nlp.io.importers import dof_number, find_dof, ground_influence, load_model
from nlp.model.nominal import shear_frame

__all__ = ["DENSE_MATRICES_MAX", "case_model", "groups_cover", "dof_index", "ground_vector"]

# Imported models up to this many DOFs are held as dense matrices (checked for symmetry and
# definiteness by full eigen-decompositions, Rayleigh damping from all their modes); larger
# ones stay sparse and use only their band's lowest modes.
DENSE_MATRICES_MAX = 400


def case_model(cfg):
    """The nominal StructuralModel of the case's model section (dense up to DENSE_MATRICES_MAX DOFs)."""
    m = cfg.model
    if m.type == "shear_frame":
        return shear_frame(m.masses, m.stiffnesses)
    model = load_model(m, cfg.path)
    if model.n > DENSE_MATRICES_MAX:
        return model
    model = model.dense()
    # symmetric M0, K0 and groups, M0 PD, K0 PSD: named by the model file
    src = m.file or m.script or (m.K.get("file") if isinstance(m.K, dict) else m.K) or cfg.path
    check_model_matrices(src, model.M0, model.K0, model.M_infl, model.K_infl)
    return model


def groups_cover(model):
    """True when the influence matrices add up to M0 and K0 (a shear frame). Otherwise a
    part of the model that no parameter scales (an imported model's other elements
    or masses) anchors the M-C-K scale."""

    def gap(A0, parts):
        rest = A0 - sum(parts) if parts else A0
        return abs(rest).max() <= 1e-9 * abs(A0).max()  # abs() works on sparse and dense

    return gap(model.M0, list(model.M_infl)) and gap(model.K0, list(model.K_infl))


def dof_index(cfg, model, key, floor, node, dof):
    """0-based row of a floor (shorthand) or of a node and DOF of an imported model."""
    n = model.n
    if node is None:
        if floor > n:
            raise InputError(cfg.path, f"{key}.floor", f"a floor (DOF) number from 1 to {n}", floor)
        if floor == 0 and (cfg.excitation.type != "ground" or model.dofs):
            raise InputError(cfg.path, f"{key}.floor", "a floor from 1 to n: a sensor on the base "
                             "(floor 0) needs ground excitation of a floor model", floor)
        return BASE_DOF if floor == 0 else floor - 1
    if not model.dofs:
        raise InputError(cfg.path, f"{key}.node", "a floor: this model has no node-to-DOF map "
                         "(model.dof_map, or an OpenSees script)", node)
    nodes = {nd for nd, _ in model.dofs}
    if node not in nodes:
        raise InputError(cfg.path, f"{key}.node", "a node tag of the model (with a free DOF)", node)
    ndf = max(d for _, d in model.dofs)
    num = dof_number(dof, 6 if ndf > 3 else ndf, model.ndm)
    i = None if num is None else find_dof(model.dofs, node, num)
    if i is None:
        free = [d for nd, d in model.dofs if nd == node]
        raise InputError(cfg.path, f"{key}.dof", f"a free DOF of node {node} (numbers {free})", dof)
    return i


def ground_vector(cfg, model):
    """Influence vector of the ground motion (None: all ones, the shear-frame case)."""
    ex = cfg.excitation
    if not model.dofs:
        if ex.direction is not None:
            raise InputError(cfg.path, "excitation.direction", "no direction: this model has no "
                             "node-to-DOF map, the ground moves every DOF", ex.direction)
        return None
    ndf = max(d for _, d in model.dofs)
    d = dof_number(ex.direction if ex.direction is not None else 1, 6 if ndf > 3 else ndf, model.ndm)
    if d is None or d > (3 if ndf >= 6 or model.ndm == 3 else 2):
        raise InputError(cfg.path, "excitation.direction", "a translation (ux, uy or uz)",
                         ex.direction)
    return ground_influence(model.dofs, d)
