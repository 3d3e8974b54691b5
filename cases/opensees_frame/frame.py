"""OpenSeesPy model of a 2-D steel moment frame: 10 storeys x 3 bays (nominal design).

Read by frf-nlp (``model.type: opensees``): it builds the model and defines
``groups``, the element groups the case updates. Units: N, m, kg, s.
Nodes are tagged 100 * level + column line (level 0 is the ground, fixed);
each free node has ux, uy and the in-plane rotation rz (DOFs 1, 2, 3).
"""

import openseespy.opensees as ops

STOREYS, BAYS = 10, 3
H, L = 3.5, 6.0                      # storey height, bay width [m]
E = 2.0e11                           # steel [Pa]
FLOOR_MASS = 60.0e3                  # kg per floor (slab, finishes, live share)
ROT_INERTIA = 20.0                   # kg m^2 per node (beam-column joint rotational inertia)


def column_section(storey):
    """(A [m^2], I [m^4]) of the columns: heavier low down, lighter in the top storeys."""
    if storey <= 3:
        return 0.030, 1.2e-3
    if storey <= 6:
        return 0.024, 9.0e-4
    return 0.018, 6.0e-4


BEAM = (0.012, 5.0e-4)               # beams: A [m^2], I [m^4]

ops.wipe()
ops.model("basic", "-ndm", 2, "-ndf", 3)
ops.geomTransf("Linear", 1)
for lev in range(STOREYS + 1):
    for col in range(BAYS + 1):
        tag = 100 * lev + col
        ops.node(tag, col * L, lev * H)
        if lev == 0:
            ops.fix(tag, 1, 1, 1)
        else:
            m = FLOOR_MASS / (BAYS + 1)
            ops.mass(tag, m, m, ROT_INERTIA)

groups = {}
for s in range(1, STOREYS + 1):
    A, I = column_section(s)
    tags = []
    for col in range(BAYS + 1):
        tag = 10000 + 100 * s + col
        ops.element("elasticBeamColumn", tag, 100 * (s - 1) + col, 100 * s + col, A, E, I, 1)
        tags.append(tag)
    groups[f"columns_story{s}"] = tags
    beams = []
    for b in range(BAYS):
        tag = 20000 + 100 * s + b
        ops.element("elasticBeamColumn", tag, 100 * s + b, 100 * s + b + 1, *BEAM[:1], E, BEAM[1], 1)
        beams.append(tag)
    groups[f"beams_story{s}"] = beams
groups["beams_lower"] = [t for s in range(1, 6) for t in groups[f"beams_story{s}"]]
groups["beams_upper"] = [t for s in range(6, STOREYS + 1) for t in groups[f"beams_story{s}"]]
