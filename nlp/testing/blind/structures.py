"""The blind benchmark's structures: design and real shear frames, non-proportional
damping, and the effects of every family of the tool at five sizes each.

Written apart from `nlp.model` on purpose (the benchmark scores the package).
"""

import numpy as np

from nlp.testing.frames import shear_K

# effect sizes per family: barely detectable ... large (the `size` recorded in truth.json
# is the dimensionless number in the comment, binned by the scorer)
SIZES = {
    "added_mass": [0.05, 0.12, 0.25, 0.45, 0.8],          # dm / floor mass
    "base_flexibility": [40.0, 15.0, 6.0, 3.0, 1.5],       # k_base / story-1 stiffness (smaller = larger effect)
    "secondary_oscillator": [0.003, 0.01, 0.025, 0.05, 0.1],  # appendage mass / floor mass
    "local_damper": [0.2, 0.5, 1.0, 2.0, 4.0],             # c / (2 zeta_1 sqrt(k m)) of the story
    "hysteretic_damping": [0.005, 0.01, 0.02, 0.04, 0.07],  # loss factor eta
    "nonadjacent_coupling": [0.03, 0.08, 0.15, 0.3, 0.5],  # k_c / mean story stiffness
    "sensor_gain": [0.02, 0.05, 0.1, 0.2, 0.35],           # |relative gain error|
    "sensor_delay": [2.0, 5.0, 10.0, 20.0, 40.0],          # delay [ms]
    "nonlinearity": [0.01, 0.03, 0.06, 0.1, 0.2],          # stiffening of the story at the high level
}
FAMILIES = tuple(SIZES)
SIZE_DETECTABLE = 2      # size rank (0..4) from which an effect counts as detectable (scored)
# the smallest local_damper size that counts as detectable
DASHPOT_CAP = SIZES["local_damper"][SIZE_DETECTABLE]


def link(n, i, j):
    """(e_i - e_j)(e_i - e_j)^T for 1-based floors, 0 = ground (dropped)."""
    e = np.zeros(n)
    if i:
        e[i - 1] += 1.0
    if j:
        e[j - 1] -= 1.0
    return np.outer(e, e)


def grow(A, couple, diag):
    """A with one more degree of freedom: coupling column `couple`, diagonal term `diag`."""
    return np.block([[A, couple[:, None]], [couple[None, :], np.array([[diag]])]])


def real_structure(rng, n, ordinary):
    """Design and real masses and story stiffnesses, and the real damping matrix."""
    m_design = rng.uniform(3.0, 8.0, n).round(2)
    k_design = rng.uniform(1500.0, 6000.0, n).round(0)
    dk, dm = (0.30, 0.10) if ordinary else (0.10, 0.05)
    k = k_design * (1 + rng.uniform(-dk, dk, n))
    m = m_design * (1 + rng.uniform(-dm, dm, n))
    M, K = np.diag(m), shear_K(k)
    w = np.sqrt(np.linalg.eigvalsh(np.linalg.solve(np.sqrt(M), np.linalg.solve(np.sqrt(M), K).T)))
    zeta = rng.uniform(0.01, 0.025)
    a1 = 2 * zeta / (w[0] + w[-1])
    a0 = a1 * w[0] * w[-1]
    C = 0.6 * (a0 * M + a1 * K)
    # the other 40 % as story dashpots of random share: damping is not proportional.
    # A story whose dashpot exceeds the median of the others by a detectable damper
    # (DASHPOT_CAP, in the local_damper family's unit) holds a concentrated damper, which a
    # structure without that effect must not: its shares are drawn again (otherwise a
    # correct damper report on a null or ordinary case is scored a false alarm; see
    # docs/benchmarks/history.md)
    unit = 2 * zeta * np.sqrt(k * m)
    while True:
        share = rng.dirichlet(np.ones(n))
        cs = 0.4 * (a0 * m.sum() / n + a1 * k.mean()) * n * share
        if dashpot_excess(cs, unit).max() < DASHPOT_CAP:
            break
    for s in range(n):
        C += cs[s] * link(n, s + 1, s)
    return {"m_design": m_design, "k_design": k_design, "m": m, "k": k, "M": M, "K": K, "C": C,
            "zeta": zeta, "f_n": w / (2 * np.pi), "dashpot_excess": dashpot_excess(cs, unit)}


def dashpot_excess(cs, unit):
    """Each story's dashpot minus the median of the other stories', in units of
    2 zeta sqrt(k_s m_s) (the local_damper family's size)."""
    return np.array([(cs[s] - np.median(np.delete(cs, s))) / unit[s] for s in range(len(cs))])


def with_effect(st, mats, family, loc, size, rng):
    """M, C, K, Kh with one more effect on top of `mats` (floors first, extra DOFs
    last) and the effect's physical parameters for truth.json."""
    M, C, K, Kh = (x.copy() for x in mats)
    n = st["M"].shape[0]
    par = {}
    if family == "added_mass":
        M[loc - 1, loc - 1] += size * st["m"][loc - 1]
        par = {"dm_kg": size * st["m"][loc - 1]}
    elif family == "local_damper":
        i, j = loc
        kk = st["k"][i - 1]
        c = size * 2 * st["zeta"] * np.sqrt(kk * st["m"][i - 1])
        C[:n, :n] += c * link(n, i, j)
        par = {"c_Ns_per_m": c}
    elif family == "hysteretic_damping":
        if loc is None:
            Kh[:n, :n] += size * st["K"]
        else:
            Kh[:n, :n] += size * st["k"][loc - 1] * link(n, loc, loc - 1)
        par = {"eta": size}
    elif family == "nonadjacent_coupling":
        i, j = loc
        kc = size * st["k"].mean()
        K[:n, :n] += kc * link(n, i, j)
        par = {"k_N_per_m": kc}
    elif family == "secondary_oscillator":
        ms = size * st["m"][loc - 1]
        # tuned near a random structural mode (within +-25 %), or between two modes
        fs = float(rng.choice(st["f_n"])) * rng.uniform(0.75, 1.25)
        zs = rng.uniform(0.01, 0.05)
        ks, cs = ms * (2 * np.pi * fs) ** 2, 2 * zs * ms * 2 * np.pi * fs
        e = np.eye(M.shape[0])[loc - 1]
        M = grow(M, 0 * e, ms)
        K = grow(K + ks * np.outer(e, e), -ks * e, ks)
        C = grow(C + cs * np.outer(e, e), -cs * e, cs)
        Kh = grow(Kh, 0 * e, 0.0)
        par = {"m_s_kg": ms, "f_s_hz": fs, "zeta_s": zs}
    elif family == "base_flexibility":
        mb = rng.uniform(0.5, 1.5) * st["m"].mean()
        kb = size * st["k"][0]
        cb = 2 * 0.05 * np.sqrt(kb * (mb + st["m"].sum()))
        one = np.ones(M.shape[0])
        # every coordinate stays relative to the table; the structure's ground
        # connections now act on (x - x_base), and the base sits on k_b, c_b
        M = grow(M, 0 * one, mb)
        K = grow(K, -K @ one, one @ K @ one + kb)
        C = grow(C, -C @ one, one @ C @ one + cb)
        Kh = grow(Kh, -Kh @ one, one @ Kh @ one)
        par = {"m_base_kg": mb, "k_base_N_per_m": kb, "c_base_Ns_per_m": cb}
    return M, C, K, Kh, par
