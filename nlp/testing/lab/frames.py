"""Frames that are not shear buildings: plane moment frames with flexible beams, condensed
to their lateral floor degrees of freedom, and planar (x, y, theta) models of eccentric
3-D frames.

Plane frame (Euler-Bernoulli, axially rigid members, rigid floors): per floor one lateral
displacement u_j and one rotation per column line. Column element (height h, EI_c) and
beam element (span L, EI_b, ends on axially rigid columns, so only end rotations)
stiffnesses are the textbook ones (Przemieniecki 1968, ch. 5); the rotations are condensed
statically (Guyan), K_u = K_uu - K_ut K_tt^-1 K_tu [N/m].

Beam-column stiffness ratio (Blume 1968; Chopra, Dynamics of Structures, sec. 18.2):
rho = sum over a floor's beams of EI_b/L / sum over a story's columns of EI_c/h.
rho -> infinity is the shear frame (each column 12 EI_c/h^3); rho = 0 leaves independent
cantilever columns (flexural beam).
"""

import numpy as np


def column_k(EI, h):
    """Lateral-rotation stiffness of a column, DOFs (u_bottom, th_bottom, u_top, th_top)."""
    return EI / h**3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                 [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])


def beam_k(EI, L):
    """End-rotation stiffness of a beam on axially rigid columns (no end translation)."""
    return EI / L * np.array([[4.0, 2.0], [2.0, 4.0]])


def frame_dofs(n, n_cols):
    """Index of u_j (floor j = 1..n) and of theta at (floor j, column line c); base fixed."""
    u = {j: j - 1 for j in range(1, n + 1)}
    th = {(j, c): n + (j - 1) * n_cols + c for j in range(1, n + 1) for c in range(n_cols)}
    return u, th


def frame_K_full(EI_c, EI_b, h, L, n_cols=2):
    """Stiffness over (u_1..u_n, rotations) of an n-storey frame: EI_c[j-1] for the
    columns of story j, EI_b[j-1] for the beams of floor j, n_cols column lines."""
    n = len(EI_c)
    u, th = frame_dofs(n, n_cols)
    K = np.zeros((n + n * n_cols,) * 2)
    for j in range(1, n + 1):
        for c in range(n_cols):
            idx = [u.get(j - 1), th.get((j - 1, c)), u[j], th[(j, c)]]   # None at the base
            ke = column_k(EI_c[j - 1], h)
            for a, ia in enumerate(idx):
                for b, ib in enumerate(idx):
                    if ia is not None and ib is not None:
                        K[ia, ib] += ke[a, b]
        for c in range(n_cols - 1):
            idx = [th[(j, c)], th[(j, c + 1)]]
            K[np.ix_(idx, idx)] += beam_k(EI_b[j - 1], L)
    return K


def condense(K, n):
    """Static condensation onto the first n DOFs: K_uu - K_ut K_tt^-1 K_tu."""
    return K[:n, :n] - K[:n, n:] @ np.linalg.solve(K[n:, n:], K[n:, :n])


def lateral_K(EI_c, EI_b, h, L, n_cols=2):
    """Condensed lateral stiffness [N/m] of the plane frame (own beam elements)."""
    return condense(frame_K_full(EI_c, EI_b, h, L, n_cols), len(EI_c))


def lateral_K_opensees(EI_c, EI_b, h, L, n_cols=2):
    """The same condensed stiffness from OpenSeesPy (elasticBeamColumn, axially stiff
    members, equalDOF floors): the flexibility under unit floor loads, inverted."""
    import openseespy.opensees as ops
    n = len(EI_c)
    E = 1.0
    # axially stiff members: EA/h some 1e8 times the bending stiffness 12 EI/h^3
    big_A = 1e8 * max(np.max(EI_c), np.max(EI_b)) / min(h, L) ** 2
    F = np.zeros((n, n))
    for load_floor in range(1, n + 1):
        ops.wipe()
        ops.model("basic", "-ndm", 2, "-ndf", 3)
        tag = lambda j, c: 1 + j * n_cols + c       # noqa: E731  node of floor j, line c
        for j in range(n + 1):
            for c in range(n_cols):
                ops.node(tag(j, c), c * L, j * h)
                if j == 0:
                    ops.fix(tag(j, c), 1, 1, 1)
        ops.geomTransf("Linear", 1)
        e = 1
        for j in range(1, n + 1):
            for c in range(n_cols):
                ops.element("elasticBeamColumn", e, tag(j - 1, c), tag(j, c), big_A, E,
                            EI_c[j - 1], 1)
                e += 1
            for c in range(n_cols - 1):
                ops.element("elasticBeamColumn", e, tag(j, c), tag(j, c + 1), big_A, E,
                            EI_b[j - 1], 1)
                e += 1
        ops.timeSeries("Constant", 1)
        ops.pattern("Plain", 1, 1)
        ops.load(tag(load_floor, 0), 1.0, 0.0, 0.0)
        ops.system("FullGeneral")
        ops.numberer("Plain")
        ops.constraints("Plain")
        ops.algorithm("Linear")
        ops.integrator("LoadControl", 1.0)
        ops.analysis("Static")
        ops.analyze(1)
        for j in range(1, n + 1):
            F[j - 1, load_floor - 1] = np.mean([ops.nodeDisp(tag(j, c), 1) for c in range(n_cols)])
    ops.wipe()
    return np.linalg.inv(0.5 * (F + F.T))


def beam_EI_for_rho(rho, EI_c, h, L, n_cols=2):
    """EI_b of every beam that gives the floor the ratio rho (per story's columns)."""
    return rho * n_cols * np.asarray(EI_c) / h * L / (n_cols - 1)


def muto_story_k(EI_c, EI_b, h, L, n_cols=2):
    """Story stiffnesses by Muto's D-value method (AIJ; Muto 1974): each column
    12 EI_c/h^3 times a = kb/(2+kb) (first story: (0.5+kb)/(2+kb)), kb = the beams'
    EI/L at the column's ends over 2 EI_c/h (first story: top beams over EI_c/h).
    The shear-frame stiffnesses a designer writes for a frame with flexible beams."""
    n = len(EI_c)
    beams_at = [1 if c in (0, n_cols - 1) else 2 for c in range(n_cols)]
    k = np.zeros(n)
    for j in range(n):
        kc = EI_c[j] / h
        top = EI_b[j] / L
        bot = EI_b[j - 1] / L if j > 0 else 0.0
        for c in range(n_cols):
            if j == 0:
                kb = beams_at[c] * top / kc
                a = (0.5 + kb) / (2 + kb)
            else:
                kb = beams_at[c] * (top + bot) / (2 * kc)
                a = kb / (2 + kb)
            k[j] += a * 12 * EI_c[j] / h**3
    return k


def cantilever_K(EI, heights):
    """Lateral stiffness of one cantilever (EI) loaded at the given heights: the inverse
    of the flexibility f_ij = x_i^2 (3 x_j - x_i) / (6 EI), x_i <= x_j."""
    x = np.asarray(heights, float)
    lo, hi = np.minimum.outer(x, x), np.maximum.outer(x, x)
    return np.linalg.inv(lo**2 * (3 * hi - lo) / (6 * EI))


def eccentric_model(m, kx, ky, plan, e, frame_pos):
    """Planar model of a 3-D frame with rigid floors, DOFs (u_x, u_y, theta) per floor at
    the plan's geometric centre O (floor j: indices 3(j-1) ... 3(j-1)+2).

    m: floor masses [kg]; kx = (kx_minus, kx_plus) story stiffnesses [N/m] of the two
    x-direction frames at y = -/+ frame_pos[1], ky those of the y-frames at x = -/+
    frame_pos[0]; plan = (a, b) [m]; e = (e_x, e_y): the centre of mass relative to O.
    Floor mass matrix at O: m [[1, 0, -e_y], [0, 1, e_x], [-e_y, e_x, r^2 + e_x^2 + e_y^2]],
    r^2 = (a^2 + b^2)/12 (uniform rectangular slab about its centre of mass).
    A frame at y = y_f moves with u_x - y_f theta; one at x = x_f with u_y + x_f theta.
    """
    n = len(m)
    a, b = plan
    ex, ey = e
    r2 = (a * a + b * b) / 12.0
    M = np.zeros((3 * n, 3 * n))
    for j in range(n):
        s = slice(3 * j, 3 * j + 3)
        M[s, s] = m[j] * np.array([[1, 0, -ey], [0, 1, ex], [-ey, ex, r2 + ex * ex + ey * ey]])
    K = np.zeros_like(M)
    frames = [(np.array([1.0, 0.0, -y]), k) for y, k in zip((-frame_pos[1], frame_pos[1]), kx)]
    frames += [(np.array([0.0, 1.0, x]), k) for x, k in zip((-frame_pos[0], frame_pos[0]), ky)]
    for t, k in frames:
        for j in range(n):
            # story j+1 joins floor j (ground for j = 0) and floor j+1
            T = np.zeros((2, 3 * n))
            T[1, 3 * j:3 * j + 3] = t
            if j > 0:
                T[0, 3 * (j - 1):3 * j] = t
            d = np.array([-1.0, 1.0])
            K += k[j] * T.T @ np.outer(d, d) @ T
    return M, K


def story_k_from_load(K, load):
    """Story stiffnesses V_j / (u_j - u_(j-1)) of a frame under a static lateral load
    (u = K^-1 load, V_j = the load at and above floor j): the shear-frame stiffnesses a
    designer reads off a lateral-load analysis of the nominal frame."""
    u = np.linalg.solve(K, load)
    V = np.cumsum(load[::-1])[::-1]
    return V / np.diff(np.concatenate([[0.0], u]))
