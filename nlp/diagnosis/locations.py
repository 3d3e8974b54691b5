"""Where added physics can sit, in the model's own terms.

A shear frame's locations are its floors (rows 1..n) and stories. An imported FE model
(:mod:`nlp.io.importers`) has nodes: its "floors" are the mass-carrying node groups, the
nodes at one elevation whose translation along the excitation direction carries mass
(a frame's levels), and its "stories" its stiffness groups. A floor is a weight vector
a_f (:func:`nlp.frf.backends.terms.floor_vector`): a_f^T u is the mean displacement of its
nodes along the direction, so an added mass dm is spread over them, an appendage hangs
from their mean, and a spring or dashpot joins two floors' means.
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["is_fe", "rigid_translation", "Floor", "floors", "floor_vectors", "mass_vectors",
           "translations",
           "mass_floors", "floor_count", "case_floors", "story_count", "floor_name",
           "fe_references", "located"]

ELEVATION_TOL = 1e-6   # relative: nodes within this of one elevation form one level


def is_fe(model):
    """Whether ``model`` is an imported FE model (rows are node DOFs), not a shear frame."""
    return bool(getattr(model, "dofs", ()))


@dataclass(frozen=True)
class Floor:
    """One location: its name, node tags and rows (empty for a shear frame's floor)."""

    name: str
    nodes: tuple
    rows: tuple


def _direction(model, ground_r):
    """The DOF number (1-based, OpenSees) the excitation moves: the ground's, else ux."""
    if ground_r is not None:
        hit = [d for (_, d), r in zip(model.dofs, ground_r) if r == 1]
        if hit:
            return hit[0]
    return 1


def rigid_translation(model, ground_r):
    """r, the rigid translation a flexible base moves the supports by: the ground's influence
    vector, else 1 on every DOF along the excitation's direction (:func:`_direction`)."""
    if ground_r is not None:
        return np.asarray(ground_r, float)
    d = _direction(model, ground_r)
    return np.array([1.0 if dof == d else 0.0 for _, dof in model.dofs])


def floors(model, ground_r=None, channel_rows=()):
    """The floors of ``model``: a shear frame's rows, or the node levels of an FE model. A
    model without node coordinates (a matrix export) has no levels to find: its locations
    are then the channels' DOFs that carry mass (``channel_rows``), each its own."""
    if not is_fe(model):
        return [Floor(f"floor {i + 1}", (), (i,)) for i in range(model.n)]
    M = sp.csr_matrix(model.M0)
    diag = M.diagonal()
    coords = dict(getattr(model, "node_coords", ()) or ())
    if not coords:
        seen = dict.fromkeys(i for i in channel_rows if 0 <= i < model.n and diag[i] > 0)
        return [Floor(f"node {model.dofs[i][0]} ({dof_name(model, model.dofs[i][1])})",
                      (model.dofs[i][0],), (i,)) for i in seen]
    d = _direction(model, ground_r)
    rows = {nd: i for i, (nd, dof) in enumerate(model.dofs) if dof == d and diag[i] > 0}
    ndm = model.ndm or (len(next(iter(coords.values()))) if coords else 1)
    levels = {}
    for nd in rows:
        z = coords[nd][ndm - 1] if nd in coords else float(nd)
        levels.setdefault(z, []).append(nd)
    heights = sorted(levels)
    span = max(abs(heights[-1] - heights[0]), 1.0) if heights else 1.0
    groups, last = [], None
    for z in heights:      # merge elevations within the tolerance
        if last is not None and z - last <= ELEVATION_TOL * span:
            groups[-1][1].extend(levels[z])
        else:
            groups.append((z, list(levels[z])))
        last = z
    out = []
    for z, nodes in groups:
        nodes = tuple(sorted(nodes))
        where = f"at {z:g} m" if coords else f"node {nodes[0]}"
        out.append(Floor(f"level {where} (nodes {_tags(nodes)})", nodes,
                         tuple(rows[nd] for nd in nodes)))
    return out


def _tags(nodes):
    return ", ".join(str(t) for t in nodes) if len(nodes) <= 4 else \
        f"{nodes[0]}, {nodes[1]}, ..., {nodes[-1]} ({len(nodes)})"


def floor_vectors(model, fl):
    """a_f per floor (n,): weight 1/|G| on each of the floor's rows."""
    out = []
    for f in fl:
        a = np.zeros(model.n)
        a[list(f.rows)] = 1.0 / len(f.rows)
        out.append(a)
    return out


def mass_vectors(model, fl):
    """b_f per floor (n,): weight 1/|nodes| on every translational DOF of each of the floor's
    nodes (DOFs 1..ndm), where a mass added at the nodes acts: a mass moves with its node in
    every direction, and a frame's vertical masses take part in its sway (the columns
    stretch under the overturning moment). Without node coordinates the translations are read
    from the DOF numbering (:func:`translations`)."""
    ndm = len(model.node_coords[0][1]) if model.node_coords else translations(model)
    out = []
    for f, a in zip(fl, floor_vectors(model, fl)):
        nodes = set(f.nodes)
        rows = [i for i, (nd, dof) in enumerate(model.dofs) if nd in nodes and dof <= ndm]
        if not rows:
            out.append(a)
            continue
        b = np.zeros(model.n)
        b[rows] = 1.0 / len(nodes)
        out.append(b)
    return out


def dof_name(model, d):
    """An engineer's name of a node's DOF number d (1..): ux, uy, uz, then rotations."""
    t = translations(model)
    if d <= t:
        return ("ux", "uy", "uz")[d - 1]
    rot = ("rz",) if t == 2 else ("rx", "ry", "rz")
    return rot[d - t - 1] if d - t <= len(rot) else f"DOF {d}"


def translations(model):
    """How many of a node's DOFs (1..) are translations, from the model's DOF map when it has
    no coordinates: ``model.ndm`` when the case states it, else by OpenSees' numbering, where
    six DOFs per node are a 3-D frame's (ux, uy, uz first) and three a 2-D frame's (ux, uy,
    rz); a map of one or two DOFs per node is all translation."""
    ndf = max((d for _, d in model.dofs), default=0)
    if model.ndm:
        return min(model.ndm, ndf)
    return 3 if ndf >= 6 else 2 if ndf == 3 else ndf


def mass_floors(model, fl):
    """The floors (1-based) where an added mass is a distinct candidate: on a model without
    coordinates two channels of one node are two locations of an appendage or a damper, but
    a mass at the node is one and the same (it moves with the node in every direction)."""
    seen, out = set(), []
    for i, b in enumerate(mass_vectors(model, fl), start=1):
        key = tuple(np.flatnonzero(b))
        if key not in seen:
            seen.add(key)
            out.append(i)
    return out


def floor_count(case):
    """Floors the families are located at (1..count)."""
    return len(case_floors(case))


def case_floors(case):
    """The case's floors (:func:`floors`) along its excitation."""
    return floors(case.model, *_along(case))


def _along(case):
    """(ground_r, channel rows) of a case, for :func:`floors`."""
    tg = getattr(case, "target", None)
    return (getattr(tg, "ground_r", None),
            tuple(ch.dof for ch in getattr(tg, "channels", ())))


def story_count(model):
    """Stories of a shear frame (its rows), stiffness groups of an FE model."""
    return len(model.K_infl) if is_fe(model) else model.n


def floor_name(model, ground_r, floor, channel_rows=()):
    """The name of floor ``floor`` (1-based; 0 is the ground)."""
    if floor == 0:
        return "the supports" if is_fe(model) else "the ground"
    return floors(model, ground_r, channel_rows)[floor - 1].name


def fe_references(model, damping, ground_r, channel_rows=()):
    """Reference magnitudes of an FE model's families: a floor's mass m_ref [kg] (the
    mass on its rows), a story's stiffness k_ref [N/m] (half the force per unit uniform
    motion of one floor, others held: two stories resist it) and damping c_ref [N s/m]
    (the same motion's damping force), each a mean over floors; the weight vectors; and
    r, the rigid translation along the excitation (the ground's influence vector)."""
    fl = floors(model, ground_r, channel_rows)
    if not fl:
        raise ValueError("an FE model without node coordinates needs channels at DOFs that "
                         "carry mass to locate added physics at")
    e = [np.bincount(list(f.rows), minlength=model.n).astype(float) for f in fl]
    M, K = sp.csr_matrix(model.M0), sp.csr_matrix(model.K0)
    try:
        C = sp.csr_matrix(damping.matrix(damping.initial(), M, K))
    except (AttributeError, TypeError, ValueError):
        C = None
    return {"r": rigid_translation(model, ground_r),
            "m_ref": float(np.mean([r @ (M @ r) for r in e])),
            "k_ref": float(np.mean([r @ (K @ r) for r in e]) / 2),
            "c_ref": float(np.mean([r @ (C @ r) for r in e])) if C is not None else 1.0,
            "floors": floor_vectors(model, fl),
            "masses": mass_vectors(model, fl)}


def located(case, e):
    """e's location for the findings: its own, with ``where`` (the place in words, node tags
    and group names) on an FE model; a shear frame's keeps its floor and story numbers."""
    loc = dict(e.location)
    model = case.model
    if not is_fe(model):
        return loc
    r, rows = _along(case)
    if e.family == "base_flexibility":
        loc["where"] = "under the supports"
    elif e.family == "added_mass" and not model.node_coords and loc.get("floor"):
        # a channel's DOF locates it, but the mass moves with its node in every direction
        loc["where"] = f"at node {floors(model, r, rows)[loc['floor'] - 1].nodes[0]}"
    elif "floor" in loc:
        loc["where"] = "at " + floor_name(model, r, loc["floor"], rows)
    elif "between" in loc and e.family == "hysteretic_damping":
        loc["where"] = f"in stiffness group {model.alpha_names[loc['between'][1] - 1]}"
    elif "between" in loc:
        a, b = loc["between"]
        loc["where"] = (f"between {floor_name(model, r, a, rows)} and "
                        f"{floor_name(model, r, b, rows)}")
    return loc
