"""The lab's real structures beyond the blind benchmark's shear frames: plane frames with
flexible beams (rho = 0.5-5) and eccentric 3-D frames seen through a planar model.

Each returns the dict the case writer reads: design values (what the case file states),
the real M, K, C, natural frequencies, and the map from the DOFs to what the floor
sensors measure (`out`: floor x-motion at the sensor, `r`: the table's influence vector,
`force_dof`: the DOF a shaker at floor j drives).
"""

import numpy as np

from nlp.testing.lab.frames import (beam_EI_for_rho, eccentric_model, lateral_K, lateral_K_opensees,
                                    story_k_from_load)

RHO = (0.5, 5.0)              # beam-column stiffness ratio of the flexible-beam frames
ECCENTRICITY = (0.03, 0.15)   # mass eccentricity / plan dimension
TORSION_RATIO = (1.0, 1.6)    # uncoupled torsional / translational frequency


def rayleigh(M, K, zeta):
    """C = a0 M + a1 K with ratio zeta at the first and last mode."""
    w = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    a1 = 2 * zeta / (w[0] + w[-1])
    return a1 * w[0] * w[-1] * M + a1 * K


def frequencies(M, K):
    """Undamped natural frequencies [Hz], ascending."""
    return np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)) / (2 * np.pi)


def shear_maps(n_dof, n):
    """Sensors and loads of a shear-type model: floor j is DOF j-1; every DOF relative."""
    return {"out": np.eye(n_dof)[:n], "r": np.ones(n_dof), "force_dof": lambda j: j - 1}


def frame_K(EI_c, EI_b, h, L):
    """Condensed lateral stiffness: OpenSeesPy when installed, else the own elements
    (the two agree to 1e-4, tests/testing/test_lab_frames.py)."""
    try:
        return lateral_K_opensees(EI_c, EI_b, h, L), "openseespy"
    except ImportError:
        return lateral_K(EI_c, EI_b, h, L), "own beam elements"


def flexible_frame(rng, n, rho):
    """A one-bay plane frame of n storeys with beam-column ratio rho. Design: the nominal
    masses and the story stiffnesses of the nominal frame under a lateral load; real:
    column and beam EI +-10 %, masses +-5 %, the full condensed K. Rayleigh damping 1-2.5 %."""
    h, L = 1.0, float(rng.uniform(1.0, 2.0))
    k_target = rng.uniform(1500.0, 6000.0, n)           # stiffness of the rigid-beam story
    EI_c_design = k_target * h**3 / 24.0
    EI_b_design = beam_EI_for_rho(rho, EI_c_design, h, L)
    m_design = rng.uniform(3.0, 8.0, n).round(2)
    # design: the nominal frame's story stiffnesses under an inverted-triangle load (the
    # first-mode-like pattern of a lateral-load analysis), i.e. exact for that load shape
    k_design = story_k_from_load(frame_K(EI_c_design, EI_b_design, h, L)[0],
                                 m_design * np.arange(1, n + 1)).round(0)
    EI_c = EI_c_design * (1 + rng.uniform(-0.1, 0.1, n))
    EI_b = EI_b_design * (1 + rng.uniform(-0.1, 0.1, n))
    m = m_design * (1 + rng.uniform(-0.05, 0.05, n))
    K, how = frame_K(EI_c, EI_b, h, L)
    M = np.diag(m)
    zeta = float(rng.uniform(0.01, 0.025))
    off = np.abs(np.triu(K, 2)).max() / np.abs(np.diag(K, 1)).max()
    st = {"m_design": m_design, "k_design": k_design, "m": m, "M": M, "K": K,
          "C": rayleigh(M, K, zeta), "zeta": zeta, "f_n": frequencies(M, K),
          "design_f_n": frequencies(np.diag(m_design), shear_K_of(k_design)),
          "frame": {"rho": float(rho), "h": h, "L": L, "EI_c": EI_c, "EI_b": EI_b,
                    "stiffness_from": how, "largest_non_adjacent_over_adjacent": float(off)}}
    st.update(shear_maps(n, n))
    return st


def shear_K_of(k):
    """Shear-chain stiffness of story stiffnesses k."""
    n = len(k)
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] = k[i] + (k[i + 1] if i + 1 < n else 0.0)
        if i + 1 < n:
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    return K


def eccentric_frame(rng, n):
    """A 3-D frame with rigid floors, two frames per direction, mass eccentric by 3-15 %
    of the plan, the x-frames' stiffnesses unequal by up to 10 %; the frames' positions
    set the uncoupled torsional/translational frequency ratio to 1.0-1.6. Measured by
    x-accelerometers off the centre; the case file describes a planar shear frame
    (x-direction story stiffnesses)."""
    a, b = float(rng.uniform(1.0, 2.0)), float(rng.uniform(1.0, 2.0))
    m_design = rng.uniform(3.0, 8.0, n).round(2)
    k_design = rng.uniform(1500.0, 6000.0, n).round(0)
    m = m_design * (1 + rng.uniform(-0.05, 0.05, n))
    kx_total = k_design * (1 + rng.uniform(-0.1, 0.1, n))
    split = 0.5 + rng.uniform(-0.05, 0.05)
    kx = (split * kx_total, (1 - split) * kx_total)
    ky_total = kx_total * rng.uniform(0.8, 1.25)
    ky = (0.5 * ky_total, 0.5 * ky_total)
    e = (float(rng.choice([-1, 1]) * rng.uniform(*ECCENTRICITY) * a),
         float(rng.choice([-1, 1]) * rng.uniform(*ECCENTRICITY) * b))
    # K_theta = (kx b_f^2 + ky a_f^2) (frames at +-a_f, +-b_f, half each); Omega^2 = K_theta /
    # (r^2 kx) with a_f/a = b_f/b = s, square-ish plan: s^2 (kx b^2 + ky a^2) / 4 = Omega^2 r^2 kx
    omega = rng.uniform(*TORSION_RATIO)
    r2 = (a * a + b * b) / 12.0
    kxm, kym = kx_total.mean(), ky_total.mean()
    s = min(np.sqrt(4 * omega**2 * r2 * kxm / (kxm * b * b + kym * a * a)), 1.0)
    M, K = eccentric_model(m, kx, ky, (a, b), e, (s * a / 2, s * b / 2))
    zeta = float(rng.uniform(0.01, 0.025))
    y_s = rng.choice([-1, 1], n) * rng.uniform(0.2, 0.45, n) * b
    out = np.zeros((n, 3 * n))
    for j in range(n):
        out[j, 3 * j], out[j, 3 * j + 2] = 1.0, -y_s[j]      # x-motion at (x_s, y_s)
    r = np.zeros(3 * n)
    r[0::3] = 1.0
    return {"m_design": m_design, "k_design": k_design, "m": m, "M": M, "K": K,
            "C": rayleigh(M, K, zeta), "zeta": zeta, "f_n": frequencies(M, K),
            "design_f_n": frequencies(np.diag(m_design), shear_K_of(k_design)),
            "out": out, "r": r, "force_dof": lambda j: 3 * (j - 1),
            "torsion": {"plan_m": [a, b], "eccentricity_m": list(e), "frame_position_share": float(s),
                        "torsion_ratio": float(omega), "sensor_y_m": y_s, "kx": kx, "ky": ky}}
