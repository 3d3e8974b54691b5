"""Whether a story is stiffer one way than the other: a breathing crack, a gap or a one-sided stop.

A restoring force that is odd in the story drift d, phi(-d) = -phi(d) (a linear spring, a
softening or hardening joint, a symmetric contact stop, friction), keeps the response to a
symmetric input symmetric. One stiffer on one side than on the other has an even part
phi_e(d) = (phi(d) + phi(-d)) / 2; for a bilinear story, k when closed (d >= 0) and
(1 - delta) k when open (d < 0), phi_e = (delta k / 2) |d|. Such a story is positively homogeneous (phi(a d) = a phi(d)
for a > 0): its equivalent linear stiffness is the same at every level, so the comparison of
levels (:mod:`nlp.diagnosis.levels`) cannot see it, and neither can any linear fit.

To first order (the drift computed by the linear model from the measured input), the outputs
carry, beyond the linear response H U,

    R_c(omega) = theta G_c(omega) b_s E_s(omega) + noise,   E_s = FFT(|d_s| - mean |d_s|),

one real coefficient theta per story, a load on the structure, so theta = -kappa for a
restoring force kappa |d| (kappa = delta k / 2 for the bilinear story; any even part of an
odd force is zero, so a symmetric joint gives theta = 0 in expectation: the even
regressor |d| is uncorrelated with every odd function of a symmetric process). Each story's
theta is the weighted least-squares estimate over the record's bins, each channel whitened by
the local level of its residual (a running median of |R|^2 over ``HALF_WIDTH`` bins each side,
over ln 2: the median of an exponential variate), so the residual's own model error widens the
estimate's error instead of biasing it. Reported: kappa [N/m] and z = kappa / SE per story.
"""

import math

import numpy as np
from scipy.ndimage import median_filter

from nlp.diagnosis.harmonics import force_frfs, story_matrix
from nlp.diagnosis.others import assemble_other
from nlp.frf.reference import load_vector

__all__ = ["model_drifts", "asymmetry", "bilinear_delta", "story_asymmetry", "with_asymmetry",
           "ASYMMETRY_Z", "ASYMMETRY_GAP"]

ASYMMETRY_Z = 6.0     # the best story's theta this many standard errors from zero ...
ASYMMETRY_GAP = 25.0  # ... and its chi-square drop this much above the next story's
HALF_WIDTH = 25       # bins each side of the running median that whitens a channel
BLOCK = 2 * HALF_WIDTH + 1   # bins per block of the sandwich standard error
F_LOW = 0.5           # bins from this fraction of the lowest fitted frequency ...
NYQUIST_USE = 0.8     # ... to this fraction of the Nyquist frequency (anti-alias filters)
REFINE_ITER, REFINE_TOL = 30, 1e-3   # the decided story's fixed point (_refined)


def model_drifts(x, fs, M, C, K, b, B):
    """Story drifts B^T q(t) [m] the linear model gives for the input record x: (n_s, N).

    b : load vector per unit input (nlp.frf.reference.load_vector); q in relative
    coordinates for ground input, so the first story's drift is its floor's displacement.
    Computed by FFT over the whole record (periodic); the mean drift is removed.
    """
    n = x.size
    U = np.fft.rfft(x)
    q = _receptance(M, C, K, 2 * np.pi * np.fft.rfftfreq(n, 1.0 / fs), b)
    D = (q @ B) * U[:, None]                       # (n_f, n_s)
    D[0] = 0.0
    return np.fft.irfft(D, n=n, axis=0).T


def _receptance(M, C, K, w, b):
    """(K - w^2 M + j w C)^-1 b at each w [rad/s] (the static K^-1 b at w = 0): (n_w, n), in
    chunks that keep the stacked matrices near 2e6 entries (a tall frame's long record)."""
    n = b.size
    out = np.empty((w.size, n), complex)
    step = max(1, int(2e6 // (n * n)))
    for a in range(0, w.size, step):
        wc = w[a:a + step, None, None]
        Z = K[None] - wc ** 2 * M[None] + 1j * wc * C[None]
        out[a:a + step] = np.linalg.solve(Z, np.broadcast_to(b, (wc.shape[0], n))[..., None])[..., 0]
    return out


def _whitening(R):
    """Local noise variance of each channel's residual: running median of |R|^2 / ln 2."""
    size = 2 * HALF_WIDTH + 1
    return np.array([median_filter(np.abs(r) ** 2, size=size, mode="nearest") / math.log(2.0)
                     for r in R])


def asymmetry(tests, M, C, K, B, channels, excitation, f_low):
    """Each story's even-force coefficient theta, its standard error, and the story the
    evidence names.

    tests : iterable of dicts with ``records`` (nlp.io.readers.TimeHistories, SI, with
        ``__input__``) and ``H_model(omega) -> (n_ch, N)``, the linear model's channel FRFs;
    M, C, K : the linear model; B : (n, n_s) story patterns (columns);
    excitation : (kind, force_dof, r) of the case's target; f_low [Hz]: lowest fitted
    frequency. Returns kappa [N/m], se, z, drop (chi-square units) per story, the bins used,
    ``best`` (index, or None when the evidence does not decide: ASYMMETRY_Z, ASYMMETRY_GAP)
    and, when decided, ``refined`` (the story's kappa with its own even force in its drift).
    """
    kind, force_dof, r = excitation
    # drift patterns (entries +-1 for a shear frame's story): B^T q is the story's drift
    B = np.asarray(B, float) / np.max(np.abs(B), axis=0)
    b = load_vector(M, kind, force_dof, r if r is None or len(r) == M.shape[0] else
                    np.concatenate([r, np.ones(M.shape[0] - len(r))]))
    num = np.zeros(B.shape[1])
    den = np.zeros(B.shape[1])
    n_bins, kept, blocks_n, blocks_d = 0, [], [], []
    for t in tests:
        rec = t["records"]
        x = np.asarray(rec.data["__input__"], float)
        n = x.size
        f = np.fft.rfftfreq(n, 1.0 / rec.fs)
        idx = np.nonzero((f >= F_LOW * f_low) & (f <= NYQUIST_USE * rec.fs / 2))[0]
        if idx.size < 4 * HALF_WIDTH:
            continue
        d = model_drifts(x, rec.fs, M, C, K, b, B)
        E = np.fft.rfft(np.abs(d) - np.abs(d).mean(axis=1, keepdims=True), axis=1)[:, idx]
        w = 2 * np.pi * f[idx]
        U = np.fft.rfft(x)[idx]
        Y = np.array([np.fft.rfft(np.asarray(rec.data[ch.name], float))[idx] for ch in channels])
        R = Y - t["H_model"](w) * U[None, :]
        s2 = _whitening(R)
        keep = np.all(s2 > 0, axis=1)
        G = force_frfs(M, C, K, w, B, channels)            # (n_idx, n_ch, n_s)
        P = np.transpose(G, (1, 0, 2)) * E.T[None]         # (n_ch, n_idx, n_s)
        wgt = np.where(keep[:, None], 1.0 / np.where(s2 > 0, s2, 1.0), 0.0)
        nb = np.einsum("cf,cfs->fs", wgt, np.real(np.conj(P) * R[..., None]))
        db = np.einsum("cf,cfs->fs", wgt, np.abs(P) ** 2)
        num += nb.sum(axis=0)
        den += db.sum(axis=0)
        # per block of contiguous bins, every channel together (common-mode noise)
        cut = np.arange(BLOCK, idx.size, BLOCK)
        blocks_n += [a.sum(axis=0) for a in np.split(nb, cut)]
        blocks_d += [a.sum(axis=0) for a in np.split(db, cut)]
        n_bins += idx.size
        kept.append({"x": x, "fs": rec.fs, "idx": idx, "d": d, "G": G, "R": R, "wgt": wgt})
    ok = den > 0
    theta = np.where(ok, num / np.where(ok, den, 1.0), 0.0)
    # Re(conj(P) R) of a complex residual of variance s2 has variance |P|^2 s2 / 2
    se = np.where(ok, 1.0 / np.sqrt(2 * np.where(ok, den, 1.0)), np.inf)
    if blocks_n:
        # residuals correlated across bins (a linear misfit times a chirp's smooth spectrum)
        # make the bins fewer than they look: the blocks' scatter about theta says how many
        bn, bd = np.array(blocks_n), np.array(blocks_d)
        sandwich = np.sqrt(np.sum((bn - theta[None] * bd) ** 2, axis=0)) / np.where(ok, den, 1.0)
        out_se = np.maximum(se, sandwich)
    else:
        out_se = se
    se = out_se
    z = theta / se
    drop = z ** 2
    order = np.argsort(drop)[::-1]
    best = int(order[0]) if drop.size else None
    gap = float(drop[order[0]] - drop[order[1]]) if drop.size > 1 else float("inf")
    decided = best is not None and abs(z[best]) > ASYMMETRY_Z and gap > ASYMMETRY_GAP
    # the restoring force's even part kappa |d|: a load -kappa b |d| on the structure
    out = {"kappa": (-theta).tolist(), "se": se.tolist(), "z": (-z).tolist(),
           "drop": drop.tolist(), "gap": gap, "bins": n_bins, "best": best if decided else None,
           "best_raw": best}
    if decided:
        out["refined"] = _refined(kept, M, C, K, B, best, float(theta[best]))
    return out


def _refined(kept, M, C, K, B, s, theta):
    """kappa of story s with the drift its own even force adds (a fixed point: the first-order
    drift ignores it, which understates kappa by a quarter to a half at delta = 0.2-0.3 on
    simulated frames). Returns kappa [N/m], iterations and whether it converged."""
    for it in range(1, REFINE_ITER + 1):
        num = den = 0.0
        for t in kept:
            n = t["x"].size
            if "T" not in t:   # story s drift per unit load b_s
                w = 2 * np.pi * np.fft.rfftfreq(n, 1.0 / t["fs"])
                t["T"] = _receptance(M, C, K, w, B[:, s]) @ B[:, s]
            T = t["T"]
            a = np.abs(t.setdefault("ds", t["d"][s]))
            E = np.fft.rfft(a - a.mean())
            D = np.fft.rfft(t["d"][s]) + T * theta * E
            D[0] = 0.0
            t["ds"] = np.fft.irfft(D, n=n)
            a = np.abs(t["ds"])
            P = t["G"][:, :, s].T * np.fft.rfft(a - a.mean())[t["idx"]][None]
            num += float(np.sum(t["wgt"] * np.real(np.conj(P) * t["R"])))
            den += float(np.sum(t["wgt"] * np.abs(P) ** 2))
        new = num / den
        if abs(new - theta) <= REFINE_TOL * abs(new):
            return {"kappa": -new, "iterations": it, "converged": True}
        theta = new
    return {"kappa": -theta, "iterations": REFINE_ITER, "converged": False}


def bilinear_delta(kappa, k_eq):
    """The stiffness loss delta of a bilinear story (k on its stiff side, (1 - delta) k on the
    other) whose even force is kappa |d| and equivalent linear stiffness k_eq = k (1 - delta/2):
    delta = r / (1 + r / 2) with r = 2 |kappa| / k_eq."""
    r = 2 * abs(kappa) / k_eq
    return r / (1 + r / 2)


def with_asymmetry(nonlin, asym):
    """The level stage's result (nlp.diagnosis.levels.nonlinearity; None for one level) with
    the test's result under "asymmetry" and its finding under "asymmetric"; one level gives a
    result with no level comparison ("levels": False)."""
    if asym is None:
        return nonlin
    out = dict(nonlin) if nonlin is not None else {"found": None, "max_z": None, "levels": False}
    out.update(asymmetry=asym["test"], asymmetric=asym["finding"])
    return out


def story_asymmetry(cfg, case, problem, z, log):
    """The test on the case's records, every level's, with the model at z (the baseline):
    {"test": :func:`asymmetry`'s result, "finding": the asymmetric story or
    None}; None without time records or story patterns (FE models) or for a sparse model."""
    if case.records is None:
        return None
    M, K, C = problem.matrices(z)
    if not all(isinstance(A, np.ndarray) for A in (M, K, C)):
        return None
    groups, B = story_matrix(case.model, M.shape[0])
    if B is None:
        return None
    records = [case.records] + [c.records for c, _ in
                                (assemble_other(cfg, p, lambda *a, **k: None)
                                 for p in cfg.data.level_files) if c is not None]
    tests = [{"records": r, "H_model": lambda w: problem.channel_frfs(z, w)}
             for r in records if r is not None]
    tg = case.target
    res = asymmetry(tests, M, C, K, B, case.channels, (tg.excitation, tg.force_dof, tg.ground_r),
                    float(case.f[case.selected].min()))
    log("asymmetry: even force of each story's drift (stiffer one way than the other), z "
        + ", ".join(f"{v:+.1f}" for v in res["z"])
        + (f": story {groups[res['best']] + 1}" if res["best"] is not None else ": none"))
    res["groups"] = groups
    finding = None
    if res["best"] is not None:
        theta = problem.theta(z)
        sa = problem.params.slices()[0]
        k_eq = case.model.alpha_nominal * (1 + theta[sa])
        finding = asymmetric_finding(res, groups[res["best"]], float(k_eq[groups[res["best"]]]))
    return {"test": res, "finding": finding}


def asymmetric_finding(res, story, k_eq):
    """The finding of an asymmetric story (index ``story``, equivalent stiffness k_eq [N/m])."""
    s = res["best"]
    ref = res["refined"]
    kappa, z = ref["kappa"], res["z"][s]
    delta = bilinear_delta(kappa, k_eq) if ref["converged"] else None
    where = f"story {story + 1} (between {'the ground' if story == 0 else f'floor {story}'} " \
            f"and floor {story + 1})"
    # kappa > 0: the restoring force kappa |d| adds to k d when d > 0 and takes from it when d < 0
    soft = "its drift is negative" if kappa > 0 else "its drift is positive"
    nxt = sorted((abs(v) for j, v in enumerate(res["z"]) if j != s), reverse=True)
    size = (f"it is about {100 * delta:.0f} % softer when {soft} (an estimate that has read "
            "low: 0.5 to 1.15 times the planted loss on simulated frames)" if delta is not None else
            f"it is softer when {soft}; how much is not determined (the estimate that includes "
            "the story's own drift did not converge)")
    statement = (
        f"{where[0].upper()}{where[1:]} is stiffer one way than the other: the response holds an "
        f"even force of its drift, {abs(z):.0f} standard errors from zero"
        + (f" (the next story {nxt[0]:.1f})" if nxt else "") + ", which a symmetric structure "
        "does not make. Read as a bilinear story (a breathing crack, a gap or a one-sided stop), "
        f"{size}. Its equivalent linear stiffness is the same at every level, so no level "
        "comparison shows it, and no family of the tool describes it: the linear model gives "
        "that equivalent stiffness.")
    return {"physics": "nonlinearity", "location": {"between": [story, story + 1]},
            "parameters": {"kappa": kappa, "bilinear_delta": delta, "k_equivalent": k_eq},
            "uncertainty": {"kappa": res["se"][s]},
            "mechanism": {"kind": "asymmetric", "z": z, "softer_when": soft,
                          "iterations": ref["iterations"], "converged": ref["converged"]},
            "evidence": {"z_per_story": res["z"], "gap": res["gap"], "bins": res["bins"]},
            "statement": statement}
