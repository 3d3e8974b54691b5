"""Table-structure and shaker-structure interaction: the excitation does not reproduce
the drive.

Shake table: a platen of mass m_t on a servo-controlled actuator, modelled in closed
loop as a spring k_a and dashpot c_a between the platen and the commanded displacement
x_c (the oil column and the servo gain; Conte and Trombetti 2000 describe the same
mechanism in a full servo-hydraulic model). With the structure's coordinates y relative
to the table (influence vector r) and the table's absolute x_t,

    [M      M r          ] [y'' ]   [C  0  ] [y' ]   [K  0  ] [y  ]   [0                  ]
    [r^T M  m_t + r^T M r] [x_t''] + [0  c_a] [x_t'] + [0  k_a] [x_t] = [k_a x_c + c_a x_c' ]

(the second row: the platen's inertia, the actuator, and the structure's base reaction
r^T M (y'' + r x_t'')). The table's acceleration x_t'' is what the input accelerometer
measures; with k_a -> infinity it equals the command.

Shaker: an armature of mass m_a on its suspension (k_s, c_s, including the back-EMF
damping of a voltage-driven amplifier) rides with the floor through a stiff stinger; the
force cell between stinger and floor measures what enters the structure,
F = F_coil - m_a a_j - c_s v_j - k_s q_j. Below the cell sit m_below [kg] (the cell's base
and mounting plate), which the structure carries.
"""

import numpy as np

TABLE_MASS = (1.0, 3.0)       # m_t / structure mass
TABLE_FREQ = (1.5, 3.0)       # bare-table closed-loop frequency / structure's highest frequency
TABLE_ZETA = (0.3, 0.6)       # closed-loop damping ratio of the bare table
ARMATURE = (0.03, 0.10)       # m_a / mass of the floor the shaker drives
SUSPENSION = (0.3, 0.8)       # suspension frequency / structure's first frequency
SHAKER_ZETA = (0.3, 1.0)      # suspension + back-EMF damping ratio
BELOW_CELL = (0.005, 0.015)   # m_below / floor mass


def with_table(M, C, K, Kh, r, m_t, k_a, c_a):
    """Matrices with the table's absolute displacement appended as the last DOF (module
    docstring); Kh (hysteretic) gets a zero row."""
    Mr = M @ r
    Ma = np.block([[M, Mr[:, None]], [Mr[None, :], np.array([[m_t + r @ Mr]])]])
    pad = lambda A, d: np.block([[A, np.zeros((A.shape[0], 1))],       # noqa: E731
                                 [np.zeros((1, A.shape[0])), np.array([[d]])]])
    return Ma, pad(C, c_a), pad(K, k_a), pad(Kh, 0.0)


def command_force(a_c, fs, f_lo, k_a, c_a):
    """k_a x_c + c_a x_c' for a commanded acceleration a_c (samples at fs): x_c by
    dividing by (j w)^2 above f_lo (a table has no stroke for lower frequencies), on the
    record zero-padded to twice its length; then the line x_c(0) + x_c'(0) t is taken off
    (zero acceleration), so that the table starts at rest."""
    N = 2 * a_c.size
    A = np.fft.rfft(a_c, N)
    w = 2 * np.pi * np.fft.rfftfreq(N, 1 / fs)
    X = np.zeros_like(A)
    keep = w >= 2 * np.pi * f_lo
    X[keep] = -A[keep] / w[keep] ** 2
    x = np.fft.irfft(X, N)[:a_c.size]
    v = np.fft.irfft(1j * w * X, N)[:a_c.size]
    t = np.arange(a_c.size) / fs
    return k_a * (x - x[0] - v[0] * t) + c_a * (v - v[0])


def table_transfer(M, C, K, r, m_t, k_a, c_a, f):
    """x_t / x_c at frequencies f [Hz] (exact, from the coupled matrices)."""
    Ma, Ca, Ka, _ = with_table(M, C, K, np.zeros_like(K), r, m_t, k_a, c_a)
    out = []
    for fk in np.atleast_1d(f):
        w = 2 * np.pi * fk
        b = np.zeros(Ma.shape[0], complex)
        b[-1] = k_a + 1j * w * c_a
        out.append(np.linalg.solve(Ka - w * w * Ma + 1j * w * Ca, b)[-1])
    return np.array(out)


def draw_table(rng, m_total, f_top):
    """m_t [kg], k_a [N/m], c_a [N s/m] of the table from the ranges above."""
    m_t = rng.uniform(*TABLE_MASS) * m_total
    w = 2 * np.pi * rng.uniform(*TABLE_FREQ) * f_top
    mt_all = m_t + m_total
    return {"m_t": float(m_t), "k_a": float(mt_all * w * w),
            "c_a": float(2 * rng.uniform(*TABLE_ZETA) * mt_all * w)}


def draw_shaker(rng, m_floor, f_first):
    """m_a, k_s, c_s of the armature and m_below of the force cell."""
    m_a = rng.uniform(*ARMATURE) * m_floor
    w = 2 * np.pi * rng.uniform(*SUSPENSION) * f_first
    return {"m_a": float(m_a), "k_s": float(m_a * w * w),
            "c_s": float(2 * rng.uniform(*SHAKER_ZETA) * m_a * w),
            "m_below": float(rng.uniform(*BELOW_CELL) * m_floor)}


def with_shaker(M, C, K, dof, sh):
    """Matrices with the armature and the cell's base carried by DOF `dof` (0-based)."""
    M, C, K = M.copy(), C.copy(), K.copy()
    M[dof, dof] += sh["m_a"] + sh["m_below"]
    C[dof, dof] += sh["c_s"]
    K[dof, dof] += sh["k_s"]
    return M, C, K


def cell_force(u, q, v, a, dof, sh):
    """The force cell's reading: the coil force less what the armature takes."""
    return u - sh["m_a"] * a[dof] - sh["c_s"] * v[dof] - sh["k_s"] * q[dof]
