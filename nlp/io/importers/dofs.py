"""Node degrees of freedom: names, numbers and the node-to-DOF map.

DOF numbers are OpenSees's, 1-based per node: in 3-D (6 DOFs per node)
1-3 are translations ux, uy, uz and 4-6 rotations rx, ry, rz; a 2-D frame node
(3 DOFs) has ux, uy and the in-plane rotation rz as 1, 2, 3. Names are accepted
wherever a number is, and are translated with the model's DOFs per node.
"""

import numpy as np

__all__ = ["DOF_LABELS", "dof_number", "find_dof", "ground_influence"]

# labels of DOF numbers 1..ndf for a node with ndf DOFs (ndm follows from ndf here)
DOF_LABELS = {
    1: ("ux",),
    2: ("ux", "uy"),
    3: ("ux", "uy", "rz"),          # 2-D frame; a 3-D truss node uses dof numbers 1-3 as ux, uy, uz
    6: ("ux", "uy", "uz", "rx", "ry", "rz"),
}
_TRUSS_3D = ("ux", "uy", "uz")


def dof_number(dof, ndf, ndm=None):
    """1-based DOF number of ``dof`` (an int or a name such as ``"uy"``), or None if invalid.

    ndf : DOFs per node of the model; ndm : spatial dimension (distinguishes a
    3-D truss node, ndf 3 = ux, uy, uz, from a 2-D frame node, ndf 3 = ux, uy, rz).
    """
    if isinstance(dof, bool):
        return None
    if isinstance(dof, (int, np.integer)):
        return int(dof) if 1 <= dof <= ndf else None
    labels = _TRUSS_3D if (ndf == 3 and ndm == 3) else DOF_LABELS.get(ndf, ())
    name = str(dof).strip().lower()
    return labels.index(name) + 1 if name in labels else None


def find_dof(dofs, node, dof):
    """Row index of (node, dof) in the node-to-DOF map ``dofs``, or None if absent."""
    for i, (nd, d) in enumerate(dofs):
        if nd == node and d == dof:
            return i
    return None


def ground_influence(dofs, direction):
    """Influence vector r of a rigid ground translation along DOF number ``direction``.

    r_i = 1 where row i is that translation of a node, else 0: the ground load is
    -M r a_g (Eqn 16 with r in place of 1 for a model with several DOFs per node).
    """
    return np.array([1.0 if d == direction else 0.0 for _, d in dofs])
