"""OpenSeesPy model of a 3-D steel moment frame: 10 storeys on a 7 x 5 column grid.

2,100 DOFs (350 free nodes, 6 DOFs each). scripts/make_frame3d.py assembles it
with OpenSees and exports M, K and the group influence matrices as the matrix
files of this case (the case itself needs no OpenSees). Units: N, m, kg, s.
Node tag 10000 * level + 100 * i + j (i: x line 0-6, j: y line 0-4; level 0
fixed). The floor mass is heavier over one corner quarter (storage), so the
sway modes in x and y and torsion couple and one horizontal force excites all.
"""

import openseespy.opensees as ops

STOREYS, NX, NY = 10, 7, 5
H, BX, BY = 3.5, 6.0, 6.0            # storey height, bay widths [m]
E, G = 2.0e11, 7.7e10                # steel [Pa]
FLOOR_MASS = 300.0e3                 # kg per floor, spread over the nodes
ROT_INERTIA = 50.0                   # kg m^2 per node and axis (joints)


def column_section(storey):
    """(A, Iy, Iz, J) [m^2, m^4] of the columns by storey."""
    if storey <= 3:
        return 0.030, 1.2e-3, 1.2e-3, 2.0e-5
    if storey <= 6:
        return 0.024, 9.0e-4, 9.0e-4, 1.5e-5
    return 0.018, 6.0e-4, 6.0e-4, 1.0e-5


# beams with their slab strip: A, Iy (vertical bending), Iz (in-plane bending, the slab makes
# the floor stiff in its plane), J
BEAM = (0.05, 5.0e-4, 2.0e-2, 1.0e-5)

ops.wipe()
ops.model("basic", "-ndm", 3, "-ndf", 6)
ops.geomTransf("Linear", 1, 1.0, 0.0, 0.0)   # columns: local x = Z
ops.geomTransf("Linear", 2, 0.0, 0.0, 1.0)   # beams: local z = Z, so Iy is vertical bending
node_mass = FLOOR_MASS / (NX * NY)
for lev in range(STOREYS + 1):
    for i in range(NX):
        for j in range(NY):
            tag = 10000 * lev + 100 * i + j
            ops.node(tag, i * BX, j * BY, lev * H)
            if lev == 0:
                ops.fix(tag, 1, 1, 1, 1, 1, 1)
            else:
                m = node_mass * (2.0 if (i >= 4 and j >= 3) else 1.0)
                ops.mass(tag, m, m, m, ROT_INERTIA, ROT_INERTIA, ROT_INERTIA)

groups = {}
for s in range(1, STOREYS + 1):
    cols, bx, by = [], [], []
    for i in range(NX):
        for j in range(NY):
            lo, hi = 10000 * (s - 1) + 100 * i + j, 10000 * s + 100 * i + j
            tag = 1000000 + hi
            ops.element("elasticBeamColumn", tag, lo, hi, *column_section(s)[:1], E, G,
                        column_section(s)[3], *column_section(s)[1:3], 1)
            cols.append(tag)
            if i + 1 < NX:
                tag = 2000000 + hi
                ops.element("elasticBeamColumn", tag, hi, hi + 100, BEAM[0], E, G, BEAM[3],
                            BEAM[1], BEAM[2], 2)
                bx.append(tag)
            if j + 1 < NY:
                tag = 3000000 + hi
                ops.element("elasticBeamColumn", tag, hi, hi + 1, BEAM[0], E, G, BEAM[3],
                            BEAM[1], BEAM[2], 2)
                by.append(tag)
    groups[f"columns_story{s}"] = cols
    groups[f"beams_x_story{s}"] = bx
    groups[f"beams_y_story{s}"] = by
for a in range(1, STOREYS, 2):        # beams updated in pairs of storeys
    groups[f"beams_x_story{a}_{a + 1}"] = groups[f"beams_x_story{a}"] + groups[f"beams_x_story{a + 1}"]
    groups[f"beams_y_story{a}_{a + 1}"] = groups[f"beams_y_story{a}"] + groups[f"beams_y_story{a + 1}"]
