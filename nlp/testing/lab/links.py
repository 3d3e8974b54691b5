"""The lab's nonlinear links, sized on the linear response of the case's own test:
slightly nonlinear joints in every shear frame, the tool's nonlinearity family, and the
effects outside the tool's families (friction, breathing crack, sliding mass)."""

import numpy as np

from nlp.testing.lab.effects import G, crack_equivalent

JOINT_CHANGE = (0.005, 0.01)   # |k_eq(3x level) - k_eq(level 1)| / k of every story's joints
JOINT_SOFTENING = 0.75         # share of stories whose joints soften
OUTSIDE_SIZES = {
    "friction": [0.03, 0.08],        # F_c / (k_s sqrt(2) sigma_d) at level 1
    "breathing_crack": [0.2, 0.4],   # delta: open-crack stiffness loss of the story
    "sliding_mass": [0.1, 0.25],     # m_s / floor mass (part of the floor's design mass)
}
OUTSIDE = tuple(OUTSIDE_SIZES)


def story_pair(s, base_dof=None):
    """(i, j) DOFs of story s (1-based): i = None is the table."""
    return (base_dof if s == 1 else s - 2), s - 1


def drift(q, s, base_dof=None):
    """Story s's drift history from the DOF histories."""
    i, j = story_pair(s, base_dof)
    return q[j] - (q[i] if i is not None else 0.0)


def active(q, u):
    """Samples while the drive is on (a chirp's quiet tail excluded)."""
    on = np.abs(u) > 0
    return q[:, on] if q.ndim == 2 else q[on]


def joints(rng, k, q1, u, base_dof=None):
    """Cubic joints on every story: 3 k3 E[d^2] (statistical linearisation) changes by
    JOINT_CHANGE x k between the level-1 drift and three times it, 24 k3 sigma_1^2."""
    out = []
    for s in range(1, len(k) + 1):
        var = float(np.var(active(drift(q1, s, base_dof), u)))
        change = rng.uniform(*JOINT_CHANGE) * (-1 if rng.uniform() < JOINT_SOFTENING else 1)
        i, j = story_pair(s, base_dof)
        out.append({"kind": "cubic", "i": i, "j": j, "story": s, "k3": change * k[s - 1] / (24 * var),
                    "change_1_to_3": float(change)})
    return out


def family_nonlinearity(rng, story, size, k_s, q3, u, base_dof=None):
    """The tool's nonlinearity family, as the blind benchmark sizes it on the level-3
    drift: cubic 3 k3 var(d) = size k, or a contact stop at gap = SD(d) with
    k_c P(|d| > gap) = size k."""
    d = active(drift(q3, story, base_dof), u)
    i, j = story_pair(story, base_dof)
    if rng.uniform() < 0.5:
        return {"kind": "cubic", "i": i, "j": j, "story": story, "k3": size * k_s / (3 * np.var(d))}
    gap = float(np.std(d))
    return {"kind": "contact", "i": i, "j": j, "story": story, "gap": gap,
            "k_c": size * k_s / max(float(np.mean(np.abs(d) > gap)), 1e-3)}


def friction(story, size, k_s, q1, v1, u):
    """Coulomb friction F_c = size k_s sqrt(2) sigma_d at story `story` (level-1 drift);
    v_0 = 2 % of the drift velocity's SD."""
    d, dv = active(drift(q1, story), u), active(drift(v1, story), u)
    i, j = story_pair(story)
    return {"kind": "friction", "i": i, "j": j, "story": story,
            "F_c": float(size * k_s * np.sqrt(2) * np.std(d)), "v0": float(0.02 * np.std(dv))}


def crack(story, size, k_s):
    """Bilinear story: k closed, (1 - size) k open."""
    i, j = story_pair(story)
    return {"kind": "crack", "i": i, "j": j, "story": story, "delta": float(size), "k": float(k_s),
            "equivalent_stiffness_ratio": float(crack_equivalent(size))}


def sliding_mass(rng, M, C, K, floor, size, a_peak, f_first, f_top):
    """Split the share `size` of floor `floor`'s mass off as a slider (a new last DOF),
    held by friction mu m_s g with mu g = 1.0-1.5 x the floor's peak absolute acceleration
    at level 1 (it sticks at level 1 and slips at 3x), and a centring spring at 0.3 f_1.
    Returns the new M, C, K and the link."""
    j = floor - 1
    m_s = size * M[j, j]
    n = M.shape[0]
    Mn = np.zeros((n + 1, n + 1))
    Mn[:n, :n] = M
    Mn[j, j] -= m_s
    Mn[n, n] = m_s
    k_r = m_s * (2 * np.pi * 0.3 * f_first) ** 2
    Kn = np.zeros_like(Mn)
    Kn[:n, :n] = K
    e = np.zeros(n + 1)
    e[j], e[n] = -1.0, 1.0
    Kn += k_r * np.outer(e, e)
    Cn = np.zeros_like(Mn)
    Cn[:n, :n] = C
    mu_g = float(rng.uniform(1.0, 1.5) * a_peak)
    link = {"kind": "slider", "i": j, "j": n, "floor": floor, "m_s": float(m_s), "mu": mu_g / G,
            "F_c": m_s * mu_g, "v0": float(0.01 * mu_g / (2 * np.pi * f_top)), "k_r": float(k_r)}
    return Mn, Cn, Kn, link
