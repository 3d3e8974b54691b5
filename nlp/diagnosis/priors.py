"""Effects inside the model class: fitted parameters against what was known.

Some effects do not raise the misfit, because the case's own free parameters
absorb them; they show only in the fitted values:

* an added mass makes a floor mass land far outside its stated prior
  (``parameters.prior`` in the case file: relative 1-sigma of the nominal
  masses and stiffnesses, or of one named parameter);
* a concentrated damper makes one story dominate the fitted C: its dashpot beyond
  the other stories' share supplies most of some mode's damping. The fitted C is
  decomposed by non-negative least squares on a mass-proportional part a0 M and
  story dashpot patterns P_s = (e_s - e_{s-1})(e_s - e_{s-1})^T (story 1 joins
  the ground); a stiffness-proportional part a1 K is itself a combination of the
  P_s with c_s = a1 k_s, so the story ratios rho_s = c_s / k_s are equal under
  Rayleigh damping and one story far above the others is a local damper (its
  dashpot beyond the others' share, as a damping ratio of the story, well above the
  structure's modal damping). A story dashpot pinned at zero by the non-negative
  fit does not enter the others' share, and no damper is claimed next to it: its
  neighbour may carry the damping it lost.
"""

import math
import re

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import nnls

__all__ = ["PRIOR_OUT", "DAMPER_RATIO", "STORY_ZETA", "DAMPER_SE", "prior_sigmas", "prior_check",
           "story_patterns", "decompose_damping", "damper_check", "modal_share",
           "story_damping_ratio"]

PRIOR_OUT = 3.0      # a value more than 3 prior sigmas from nominal is "far outside its prior"
DAMPER_RATIO = 2.0   # a damper's story has c_s / k_s at least 2x the others' median, and
STORY_ZETA = 1.85    # its excess dashpot, as the damping ratio of its story (c / 2 sqrt(k_s m_s)),
                     # is 1.85x the median modal damping ratio of the structure without it:
                     # random story dashpots (40 % of C, Dirichlet shares) pass in 2.0-2.1 % of
                     # draws, a dashpot of 2 (4) x 2 zeta sqrt(k m) in 81 % (100 %), 65-69 % on
                     # 3-storey frames; measured against the median with the damper in (1.35x):
                     # 2.1-2.4 %, 69-70 % (95-96 %), 47-48 % (true matrices, seeds 2 and 3 of
                     # python scripts/damper_threshold.py)
DETERMINED = 6.0     # a parameter outside its prior must also stand this many SE from nominal
DAMPER_SE = 3.0      # ... and a damper's excess this many from zero. It was DETERMINED (6)
                     # after the code of an earlier time claimed dampers wrongly at 3.2-5.3 SE
                     # (the n story dashpots of a weakly identified general C); those cases
                     # are now refused by the zeta test or the structured refit at any number
                     # of SEs. Replayed on 229 stored decompositions of earlier benchmark
                     # cases (python scripts/replay_damper_rule.py): 3 adds two right stories
                     # and no wrong one (see docs/method/diagnosis.md)
MAX_UNEXPLAINED = 0.3  # a C this far from M + story patterns is not decomposed into dampers


def prior_sigmas(prior, params):
    """Relative 1-sigma prior of each free mass and stiffness parameter.

    prior : dict from ``parameters.prior`` ({"masses": 0.1, "stiffnesses": 0.25,
    "<name>": s}); returns {name: s} for the parameters it covers.
    """
    out = {}
    if not prior:
        return out
    for p in params.params:
        if p.fixed or p.group not in ("mass", "stiffness"):
            continue
        s = prior.get(p.name, prior.get("masses" if p.group == "mass" else "stiffnesses"))
        if s is not None:
            out[p.name] = float(s)
    return out


def prior_check(params, theta, se_theta, sigmas):
    """Parameters far outside their prior, and determined well enough to say so.

    theta, se_theta : relative changes (Eqns 23-24) and their standard errors, in the
    order of ``params.params``. A parameter is reported when |theta| > PRIOR_OUT
    prior sigmas and > DETERMINED standard errors. Returns a list of dicts with the
    physical value [kg or N/m], nominal, relative change, its error and z_prior.
    """
    out = []
    for i, p in enumerate(params.params):
        s = sigmas.get(p.name)
        if s is None:
            continue
        d, se = float(theta[i]), float(se_theta[i])
        if abs(d) > PRIOR_OUT * s and abs(d) > DETERMINED * se:
            nom = p.nominal
            out.append({"parameter": p.name, "group": p.group, "nominal": nom,
                        "value": nom * (1 + d), "relative_change": d, "standard_error": se,
                        "prior_sigma": s, "z_prior": d / s})
    return out


def floor_of_mass(name):
    """Floor number of a shear-frame mass name m<i>, else None."""
    m = re.fullmatch(r"m(\d+)", name)
    return int(m.group(1)) if m else None


def story_patterns(n):
    """Dashpot patterns of the n stories of a shear frame (story s joins floors s-1, s)."""
    P = []
    for s in range(n):
        e = np.zeros(n)
        e[s] = 1.0
        if s > 0:
            e[s - 1] = -1.0
        P.append(np.outer(e, e))
    return P


def _vec(A):
    iu = np.triu_indices(A.shape[0])
    w = np.where(iu[0] == iu[1], 1.0, math.sqrt(2.0))  # Frobenius norm of the symmetric matrix
    return A[iu] * w


def decompose_damping(C, M):
    """Non-negative least squares C ~ a0 M + sum_s c_s P_s.

    Returns (a0 [1/s], c (n,) [N s/m], fraction of ||C||_F left unexplained).
    """
    n = C.shape[0]
    B = np.column_stack([_vec(M)] + [_vec(P) for P in story_patterns(n)])
    x, rn = nnls(B, _vec(0.5 * (C + C.T)))
    return float(x[0]), x[1:], float(rn / max(np.linalg.norm(_vec(C)), 1e-300))


def story_stiffness(K):
    """Story stiffnesses k_s of a shear-frame K (k_1 to the ground)."""
    n = K.shape[0]
    k = np.empty(n)
    for s in range(1, n):
        k[s] = -K[s, s - 1]
    k[0] = K[0, 0] - (k[1] if n > 1 else 0.0)
    return k


def damping_excess(C, M, K, leave_out=None):
    """Each story's dashpot beyond the proportional share of the other stories (the
    median of their c / k, without the stories of the boolean mask ``leave_out`` while
    any other remains)."""
    _, c, _ = decompose_damping(C, M)
    k = story_stiffness(K)
    rho = c / np.maximum(k, 1e-300)
    out = np.zeros(rho.size, bool) if leave_out is None else np.asarray(leave_out, bool)
    ref = np.zeros(rho.size)
    for s in range(rho.size):
        others = np.delete(rho, s)
        kept = others[~np.delete(out, s)]
        ref[s] = np.median(kept if kept.size else others) if others.size else 0.0
    return c - ref * k, rho, ref, c


def damper_check(problem, z, cov_z):
    """Concentrated dampers in the fitted C of a shear frame.

    problem : nlp.solve.problem.UpdatingProblem (its numeric matrices(z)); cov_z : covariance
    of z. The errors of the excess are propagated by central differences.
    Returns (decomposition dict, list of flagged stories with excess [N s/m] and SE).
    """
    M, K, C = problem.matrices(z)
    n = M.shape[0]
    if n < 2:
        return None, []
    a0, c, left = decompose_damping(C, M)
    # a story dashpot pinned at zero by the non-negative fit: the fitted C leaves the family
    # a0 M + story dashpots there. It is no measure of the others' share, and its neighbour
    # may have taken its damping (on a null case, a pinned story 1 with a0 at twice the
    # truth made story 2 read as a damper at "20 standard errors"); a damper away from it
    # stands (a true damper two stories away was found, close to its value, while story 1
    # was pinned; see docs/method/diagnosis.md)
    pinned = c <= 1e-9 * max(float(np.max(c)), 1e-300)
    ex, rho, ref, _ = damping_excess(C, M, K, pinned)
    lo, hi = problem.bounds
    G = np.zeros((n, z.size))
    for j in range(z.size):
        h = 1e-6 * max(1.0, abs(z[j]))
        zp, zm = z.copy(), z.copy()
        zp[j] = min(z[j] + h, hi[j]) if np.isfinite(hi[j]) else z[j] + h
        zm[j] = max(z[j] - h, lo[j]) if np.isfinite(lo[j]) else z[j] - h
        if zp[j] == zm[j]:
            continue
        G[:, j] = (damping_excess(*_mck(problem, zp), pinned)[0]
                   - damping_excess(*_mck(problem, zm), pinned)[0]) / (zp[j] - zm[j])
    se = np.sqrt(np.clip(np.einsum("ij,jk,ik->i", G, cov_z, G), 0, None))
    info = {"a0": a0, "story_dashpots": c.tolist(), "story_ratio_c_over_k": rho.tolist(),
            "unexplained_fraction": left}
    share = modal_share(M, K, C, ex)
    info["largest_modal_share"] = share.max(axis=1).tolist()
    # the thresholds are met by the excess one standard error below its estimate: a
    # null's random dashpots can come near them (a modal share about 0.1 over its true
    # value, see docs/method/diagnosis.md), and a point estimate just over them is not a damper
    ex_lo = np.clip(ex - se, 0.0, None)
    share_lo = modal_share(M, K, C, ex_lo).max(axis=1)
    rho_lo = ref + ex_lo / np.maximum(story_stiffness(K), 1e-300)
    zeta_lo, zeta_med = story_damping_ratio(M, K, C, ex_lo, removed=ex)
    info["median_modal_damping_ratio_without_story"] = zeta_med.tolist()
    info["story_zeta_ratio_lower"] = zeta_lo.tolist()
    info["pinned_stories"] = [int(s + 1) for s in np.nonzero(pinned)[0]]
    info.update({"excess": ex.tolist(), "excess_se": se.tolist(),
                 "ratio_to_others": (rho / np.maximum(ref, 1e-300)).tolist(),
                 "modal_share_lower": share_lo.tolist()})
    flagged = []
    for s in range(n):
        if (left < MAX_UNEXPLAINED and ref[s] > 0 and ex[s] > DAMPER_SE * se[s]
                and not pinned[max(s - 1, 0):s + 2].any()
                and rho_lo[s] > DAMPER_RATIO * ref[s] and zeta_lo[s] > STORY_ZETA):
            flagged.append({"story": s + 1, "excess": float(ex[s]), "standard_error": float(se[s]),
                            "ratio": float(rho[s] / ref[s]),
                            "story_zeta_ratio": float(story_damping_ratio(M, K, C, ex)[0][s]),
                            "story_zeta_ratio_lower": float(zeta_lo[s]),
                            "modal_share": float(share[s].max()),
                            "modal_share_lower": float(share_lo[s])})
    return info, flagged


def modal_share(M, K, C, excess):
    """Share of each real mode's damping phi^T C phi supplied by each story's excess
    dashpot excess_s (phi_s - phi_{s-1})^2: (n stories, n modes), dimensionless.

    A story dashpot that supplies more than half of a mode's damping dominates it;
    damping that is merely non-proportional spreads over the stories.
    """
    _, phi = eigh(K, M)
    drift = np.diff(np.vstack([np.zeros((1, phi.shape[1])), phi]), axis=0)  # story drifts
    total = np.einsum("ir,ij,jr->r", phi, 0.5 * (C + C.T), phi)
    return np.clip(np.asarray(excess)[:, None], 0, None) * drift ** 2 / np.maximum(total, 1e-300)


def story_damping_ratio(M, K, C, excess, removed=None):
    """Each story's excess dashpot as the damping ratio of its story oscillator,
    excess_s / (2 sqrt(k_s m_s)) (m_s the mass of floor s), over the median modal damping
    ratio phi^T C' phi / (2 omega) (mass-normalised real modes) of the structure without
    that story's dashpot, C' = C - removed_s P_s (``removed`` defaults to ``excess``;
    negative values remove nothing).

    The damper is left out of its own yardstick: on a 3-storey frame it can set the median
    of three modes by itself (a dashpot twice its story's share measured 1.01x with it in,
    while its story supplied 60 % of one mode).

    Returns ((n,) ratios [-], (n,) median modal damping ratios of each C' [-]).
    """
    w2, phi = eigh(K, M)
    excess = np.asarray(excess, float)
    removed = excess if removed is None else np.asarray(removed, float)
    drift = np.diff(np.vstack([np.zeros((1, phi.shape[1])), phi]), axis=0)  # story drifts
    two_w = 2 * np.sqrt(np.maximum(w2, 1e-300))
    zeta = np.einsum("ir,ij,jr->r", phi, 0.5 * (C + C.T), phi) / two_w
    zmed = np.array([float(np.median(zeta - max(r, 0.0) * drift[s] ** 2 / two_w))
                     for s, r in enumerate(removed)])
    unit = 2 * zmed * np.sqrt(np.maximum(story_stiffness(K) * np.diag(M), 1e-300))
    return excess / np.maximum(unit, 1e-300), zmed


def _mck(problem, z):
    M, K, C = problem.matrices(z)
    return C, M, K
