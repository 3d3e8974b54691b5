"""Whether a case's records determine its planted effect: the Cramer-Rao bound with the model
class free.

"Detectable" was a size rank. What a diagnosis can name is bounded by what the records
determine: the standard error of the effect's strength p (null p = 0) when everything a
case's model leaves free is estimated beside it. Written apart from `nlp` (the benchmark
scores the package), from the lab's own matrices:

* residuals ln H_c(w) of every recorded channel (accelerations, table-relative
  displacements) at the bins of the case's band whose coherence reaches the case's
  min_coherence; each complex residual has real and imaginary parts of variance
  sigma^2 = (1 - gamma^2) / (2 n_d gamma^2) (Bendat and Piersol, Random Data, 2010,
  eqs. 9.52-9.53: the random errors of a gain and phase estimate), gamma^2 the coherence of
  the records and n_d the Welch segments of the estimate (50 % overlap, Hann: K / 1.056);
* the model class free beside p: every floor mass and story stiffness (with the prior the
  case states as information 1 / (s m)^2 on each: an added mass shows as a floor mass
  beyond its prior), a general symmetric C over the floors, and a gain of every channel
  (the calibration the case states is a box the tool fits inside; free here, so the
  bound is the looser one);
* the effect's own shaping parameters free too (an appendage's tuning and damping, a
  base's mass and dashpot), as a diagnosis must find them.

F = Re(J^H J) / sigma^2 summed over channels and bins; the standard error of p is
(F_pp - F_pn F_nn^+ F_np)^(-1/2). An effect counts as detectable when p / SE(p) >= RATIO:
the tool names an effect 3 standard errors from its null (SIGNIFICANCE), and an efficient
estimate of an effect RATIO = 3 + 1.645 SE from its null passes that test with probability
0.95. The bound is the ideal (right model, efficient estimate, all bins of the band); a
real diagnosis needs more, so the rule errs toward counting an effect detectable.

A local damper is a change of C, which the model class leaves free (a general C), so its
bound is no bound; what tells it apart is one story's dashpot standing out from the others,
and the lab's nulls carry random story dashpots up to the blind benchmark's DASHPOT_CAP (the
size of a rank-2 damper): a damper counts as detectable above that cap (:func:`damper_rule`).
Sensor gains, delays and level dependence keep the size rank: a gain is exactly a channel's
calibration nuisance in this bound, a delay lives in the phase of one channel against
conditioning delays, and a level dependence in two records.
"""

import numpy as np
from scipy import signal

__all__ = ["RATIO", "FISHER_FAMILIES", "damper_rule", "channel_frfs", "log_jacobian", "noise_sd",
           "effect_derivative", "nuisance_derivatives", "standard_error", "detectability"]

RATIO = 3.0 + 1.645   # a 3-SE test (the tool's SIGNIFICANCE) with 95 % power
FISHER_FAMILIES = ("added_mass", "base_flexibility", "secondary_oscillator",
                   "hysteretic_damping", "nonadjacent_coupling")
HANN_OVERLAP = 1.056   # variance factor of 50 %-overlapped Hann segments (1 + 2 rho^2, rho 0.167)


def damper_rule(size, cap):
    """A local damper of this size (its dashpot over 2 zeta sqrt(k m) of its story) is told
    from a null's random story dashpots only above their cap."""
    return {"rule": "dashpot_cap", "size": float(size), "cap": float(cap),
            "detectable": bool(size > cap)}


def _Z(mats, w):
    M, C, K, Kh = mats
    return K + 1j * Kh - w ** 2 * M + 1j * w * C


def _outputs(y, w, kinds, ground):
    """Channel outputs from the DOF combinations y at w: absolute acceleration per unit
    input ('acc'; a ground test adds the table's own 1) or displacement ('lvdt')."""
    return np.array([(1.0 if ground else 0.0) - w ** 2 * y[c] if kd == "acc" else y[c]
                     for c, kd in enumerate(kinds)])


def _load(M, r, ground, force_dof):
    return -M @ r if ground else np.eye(M.shape[0])[force_dof]


def channel_frfs(mats, w, out_rows, kinds, ground, force_dof, r):
    """(n_ch, n_w) FRFs: ground input (table acceleration) -> absolute acceleration
    ('acc') or table-relative displacement ('lvdt'); force input -> acceleration or
    displacement. out_rows (n_ch, n_dof) picks each channel's DOF combination."""
    b = _load(mats[0], r, ground, force_dof)
    return np.array([_outputs(out_rows @ np.linalg.solve(_Z(mats, wk), b), wk, kinds, ground)
                     for wk in w]).T


def log_jacobian(mats, dmats, w, out_rows, kinds, ground, force_dof, r):
    """d ln H / d theta, (n_ch, n_w, n_theta): dmats a list of (dM, dC, dK, dKh) per
    parameter (the load -M r of a ground test moves with M)."""
    b = _load(mats[0], r, ground, force_dof)
    J = np.empty((len(kinds), w.size, len(dmats)), complex)
    for k, wk in enumerate(w):
        Z = _Z(mats, wk)
        x = np.linalg.solve(Z, b)
        h = _outputs(out_rows @ x, wk, kinds, ground)
        for j, d in enumerate(dmats):
            db = -d[0] @ r if ground else 0.0 * b
            dx = np.linalg.solve(Z, db - _Z(d, wk) @ x)
            # the table's own 1 does not move: the derivative has no constant term
            J[:, k, j] = _outputs(out_rows @ dx, wk, kinds, False) / h
    return J


def noise_sd(x_in, ys, fs, nperseg, f):
    """(n_ch, len(f)) SD of ln|H| (and of its phase) from the records' coherence, and the
    coherence itself, at the bins f of the Welch estimate (Hann, 50 % overlap)."""
    n_d = max((x_in.size - nperseg) // (nperseg // 2) + 1, 1) / HANN_OVERLAP
    sd, coh = [], []
    for y in ys:
        fc, g2 = signal.coherence(x_in, y, fs=fs, window="hann", nperseg=nperseg,
                                  noverlap=nperseg // 2)
        g2 = np.interp(f, fc, g2)
        coh.append(g2)
        sd.append(np.sqrt((1 - g2) / (2 * n_d * np.maximum(g2, 1e-12))))
    return np.array(sd), np.array(coh)


def _lift(d, n, n_all, base):
    """An n x n change of the floors' matrix in the system's n_all DOFs: padded, or on a
    flexible base (coordinates relative to the table, ground links acting on x - x_base)
    with the base row and column the grown matrix gives it."""
    out = np.zeros((n_all, n_all))
    out[:n, :n] = d
    if base is not None:
        one = np.zeros(n_all)
        one[:n] = 1.0
        col = -d @ one[:n]
        out[:n, base] = col
        out[base, :n] = col
        out[base, base] = one[:n] @ d @ one[:n]
    return out


def nuisance_derivatives(st, n_all, base):
    """(dM, dC, dK, dKh) of every floor mass, story stiffness and general-C entry."""
    n = st["M"].shape[0]
    zero = np.zeros((n_all, n_all))
    out = []
    for j in range(n):
        e = np.zeros((n, n))
        e[j, j] = 1.0
        dm = np.zeros((n_all, n_all))
        dm[:n, :n] = e
        out.append((dm, zero, zero, zero))
    for s in range(n):                          # story s + 1: floor s to floor s - 1
        v = np.zeros(n)
        v[s] = 1.0
        if s:
            v[s - 1] = -1.0
        out.append((zero, zero, _lift(np.outer(v, v), n, n_all, base), zero))
    for i in range(n):
        for j in range(i, n):
            e = np.zeros((n, n))
            e[i, j] = e[j, i] = 1.0
            out.append((zero, _lift(e, n, n_all, base), zero, zero))
    return out


def effect_derivative(family, st, mats, truth_par, size):
    """((dM, dC, dK, dKh) per unit of the effect's strength p, p at the truth, [the same of
    each shaping parameter]). p is the added share (added mass, appendage mass ratio, loss
    factor, coupling: every matrix entry the effect adds is proportional to it) or the base's
    flexibility k_1 / k_b."""
    n_all = mats[0].shape[0]
    n = st["M"].shape[0]
    z = np.zeros((n_all, n_all))
    if family == "base_flexibility":
        b = n_all - 1
        E = z.copy()
        E[b, b] = 1.0
        p = 1.0 / size                          # size = k_b / k_1
        kb = truth_par["k_base_N_per_m"]
        return (z, z, -kb / p * E, z), p, [(E, z, z, z), (z, E, z, z)]   # m_b, c_b
    base = [z.copy() for _ in range(4)]
    for A, B in zip(base, (st["M"], st["C"], st["K"], np.zeros_like(st["K"]))):
        A[:n, :n] = B
    added = [np.asarray(m, float) - b for m, b in zip(mats, base)]
    shaping = []
    if family == "secondary_oscillator":     # k_s = m_s w_s^2, c_s = 2 zeta_s m_s w_s
        f_s, z_s = truth_par["f_s_hz"], truth_par["zeta_s"]
        shaping = [(z, added[1] / f_s, 2 * added[2] / f_s, z), (z, added[1] / z_s, z, z)]
    return tuple(a / size for a in added), size, shaping


def standard_error(J, sd, prior=None):
    """SE of parameter 0 with the others free: J (n_ch, n_w, n_theta) over residuals of
    SD sd (n_ch, n_w), NaN where not used; prior: optional (n_theta,) prior SDs (inf: none)."""
    ok = np.isfinite(sd)
    Jw = J[ok] / sd[ok][:, None]
    F = np.real(Jw.conj().T @ Jw)
    if prior is not None:
        F = F + np.diag(1.0 / np.asarray(prior, float) ** 2)
    Fpp, Fpn, Fnn = F[0, 0], F[0, 1:], F[1:, 1:]
    s = Fpp - Fpn @ np.linalg.pinv(Fnn, rcond=1e-12) @ Fpn
    return float(1 / np.sqrt(s)) if s > 0 else float("inf")


def detectability(family, size, truth_par, st, mats, system, test, records, case):
    """{"rule", "p", "se", "ratio", "detectable"} of one planted structural effect.

    records : {column: signal} at the recording rate (the case's records, first level).
    case : the case file's dict (its band, min_coherence, nominal model and prior).
    """
    fq = case["frequencies"]
    band, min_coh = (fq["fmin"], fq["fmax"]), fq.get("min_coherence", 0.0)
    fs, nperseg = test["fs"], (4096 if test["fs"] == 100.0 else 8192)
    ground = test["excitation"] == "ground"
    names = [f"acc{i + 1}" for i in range(test["storeys"])] + [f"lvdt{i}" for i in test["lvdt_floors"]]
    kinds = ["acc" if c.startswith("acc") else "lvdt" for c in names]
    out = np.asarray(system["out"], float)
    rows = np.vstack([out[i] for i in range(test["storeys"])]
                     + [out[i - 1] for i in test["lvdt_floors"]])
    f = np.fft.rfftfreq(nperseg, 1 / fs)
    keep = (f >= band[0]) & (f <= band[1])
    f = f[keep]
    sd, coh = noise_sd(np.asarray(records["input"]), [np.asarray(records[c]) for c in names],
                       fs, nperseg, f)
    sd = np.where(coh >= min_coh, sd, np.nan)
    n_all = mats[0].shape[0]
    base = system.get("base_dof") if family == "base_flexibility" else None
    d_eff, p, shaping = effect_derivative(family, st, mats, truth_par, size)
    dmats = [d_eff] + shaping + nuisance_derivatives(st, n_all, base)
    w = 2 * np.pi * f
    J = log_jacobian(tuple(np.asarray(m, float) for m in mats), dmats, w, rows, kinds, ground,
                     system.get("force_dof"), np.asarray(system["r"], float))
    gains = np.zeros(J.shape[:2] + (len(names),), complex)
    for c in range(len(names)):
        gains[c, :, c] = 1.0
    pr = (case.get("parameters") or {}).get("prior") or {}
    m0, k0, n = case["model"]["masses"], case["model"]["stiffnesses"], st["M"].shape[0]
    prior = ([np.inf] * (1 + len(shaping)) + [pr.get("masses", np.inf) * m for m in m0]
             + [pr.get("stiffnesses", np.inf) * k for k in k0]
             + [np.inf] * (n * (n + 1) // 2 + len(names)))
    se = standard_error(np.concatenate([J, gains], axis=2), sd, prior)
    return {"rule": "fisher", "p": float(p), "se": se, "ratio": float(abs(p) / se),
            "detectable": bool(abs(p) / se >= RATIO), "ratio_needed": RATIO}
