"""The joints' distortion of a one-segment record's FRF, estimated and removed.

Every real frame's joints make its stories slightly level-dependent (about 1 % of
equivalent stiffness between a level and three times it; :mod:`.materiality`). Under
random drive that shows as a little lost coherence, which the Welch noise model counts.
A chirp estimated in one segment has no coherence to lose, and it passes each
resonance with the response many times its record RMS: the joints bend its peaks by
several per cent of ln|H| (on a development null with 0.7-1 % joints, 5-8 % at the
first two modes, 10x the noise there; with the joints removed from the same
simulation the baseline fitted to the noise, reduced chi-square 0.82). No linear model
has a bent peak, so an adequate frame read as a model that misses.

The distortion is computed as a series in the story springs: a cubic spring k3 d^3 across
story s adds the internal force -k3 d_s(t)^3 with the story's pattern b_s, d_s the drift
the linear model predicts from the measured input, and the forces' own response is fed
back ITERATIONS times. Over the linear response Y_lin = H U the channels read

    ln H_data - ln H_lin = ln(1 + G(w) sum_s b_s P_s(w) / (H(w) U(w))),  P_s = FFT(-k3_s d_s^3),
    G = (K - w^2 M + j w C)^-1 (channel outputs),

whose first-order term is linear in the k3_s. They are estimated by Gauss-Newton on the
baseline's residuals together with the baseline's own Jacobian (so the linear model does
not keep what it absorbed of the bend). When every story's equivalent change between
the level and three times it, 24 k3_s Var(d_s) / k_s, stays within the joints' band
(:data:`nlp.diagnosis.materiality.JOINT_CHANGE`) and the k3 lower the chi-square by
more than BIC's price, the data are divided by exp(distortion) and the correction's own
error is added to the noise: what follows is diagnosed on the frame's linear FRF. A
larger level dependence is left in the data: it is the structure's, for the rest of the
diagnosis to name.

Checked against an independent RK4 simulation of a frame with cubic joints
(tests/diagnosis/test_sweep.py) and on the lab generator's development nulls
(docs/method/diagnosis.md, "A sweep's joints").
"""

import math
from dataclasses import replace

import numpy as np

from nlp.diagnosis.checkpoint import fingerprint, logged_step
from nlp.diagnosis.decide import windows_explained
from nlp.diagnosis.fitting import (best_fit, diagnosis_problem, fit_target, noise_sigma,
                                   normalised, signed)
from nlp.diagnosis.harmonics import force_frfs, story_matrix
from nlp.diagnosis.materiality import JOINT_CHANGE
from nlp.frf.reference import channel_frfs, load_vector
from nlp.frf.variance import rest_mask

__all__ = ["applies", "story_patterns", "response_setup", "distortion", "distortion_basis",
           "estimate", "corrected", "sweep_stage", "final_sweep", "carried", "as_measured",
           "MAX_DOF"]

MAX_DOF = 24          # shear frames: one cubic spring per story (the s x s drift response
                      # per frequency of a long record grows as s^2)
BLOCK = 4096          # frequencies solved at a time
BIC_ACCEPT = 10.0     # as nlp.diagnosis.evidence: "very strong" (Kass & Raftery)
GN_STEPS = 3          # Gauss-Newton steps of k3 (the first is the first-order estimate)
ITERATIONS = 4        # fixed-point passes of the story forces' own response
MAX_LN = 0.5          # the series is trusted up to this distortion of ln H
# the correction's error, relative to the distortion removed: on an independent simulation
# (tests/diagnosis/test_sweep.py) 95 % of the bins came within a tenth of their distortion
# with the true k3, and on development records the fitted k3 were 5-15 % off the planted
REL_ERROR = 0.1


def applies(case):
    """A single segment of time histories (chirp or transient): the route whose estimate
    carries the joints' bend without any loss of coherence to show it."""
    rec, d = case.records, case.config.data
    return (rec is not None and "__input__" in rec.data and d.nperseg == "all"
            and case.config.objective.residual == "log_magnitude"
            and int(getattr(case, "n_averages", 1) or 1) == 1 and not d.tests)


def _drive(case):
    x = np.asarray(case.records.data["__input__"], float)
    return x - x.mean(), case.records.fs


def response_setup(M, C, K, B, case):
    """What the distortion needs of the linear model (M, C, K; story patterns B of +-1) and
    the record: the drifts' linear spectra on the zero-padded record grid, the drift per
    unit story force there, and on case.f the channels' linear outputs Y = H U and their
    outputs per unit story force G; the drifts' variances over the driven samples."""
    u, fs = _drive(case)
    n = u.size
    L = 2 * n                                # zero-padded: no wrap-around of the tail
    w = 2 * np.pi * np.fft.rfftfreq(L, 1.0 / fs)
    tg = case.target
    U = np.fft.rfft(u, L)
    wp = np.maximum(w, 1e-6)
    b = load_vector(M, tg.excitation, tg.force_dof, tg.ground_r)
    D = np.empty((B.shape[1], w.size), complex)          # the drifts' linear spectra
    T = np.empty((w.size, B.shape[1], B.shape[1]), complex)   # drift per unit story force
    for a in range(0, w.size, BLOCK):                    # a block of frequencies at a time
        wb = wp[a:a + BLOCK]
        Z = K[None] - wb[:, None, None] ** 2 * M[None] + 1j * wb[:, None, None] * C[None]
        X = np.linalg.solve(Z, np.broadcast_to(np.column_stack([b, B]), (wb.size, b.size,
                                                                           B.shape[1] + 1)))
        D[:, a:a + BLOCK] = (B.T @ X[:, :, 0].T) * U[None, a:a + BLOCK]
        T[a:a + BLOCK] = B.T[None] @ X[:, :, 1:]
    rec = case.records
    y = np.array([rec.data[ch.name] for ch in case.channels if ch.name in rec.data])
    rest = rest_mask(u, y, fs) if y.size else None
    driven = ~rest if rest is not None and (~rest).sum() > 16 else np.ones(n, bool)
    var = np.fft.irfft(D, L, axis=1)[:, :n][:, driven].var(axis=1)
    # the case's grid is the record's own (every other bin of the padded one)
    keep = np.rint(np.asarray(case.f) * L / fs).astype(int).clip(0, w.size - 1)
    wk = wp[keep]
    Y = channel_frfs(M, C, K, wk, case.channels, tg.excitation, tg.force_dof, tg.ground_r) \
        * U[keep][None, :]
    G = force_frfs(M, C, K, wk, B, case.channels)                  # (n_f, n_ch, n_s)
    return {"n": n, "L": L, "D": D, "T": T, "keep": keep, "Y": Y, "G": G, "var": var}


def _force(pre, k3, iters):
    """Spectra of the story forces -k3_s d_s^3 (n_s, n_w), the drifts d from the linear
    response and `iters` fixed-point passes of the forces' own response (0: first order)."""
    n, L = pre["n"], pre["L"]
    D = pre["D"]
    k3 = np.asarray(k3, float)[:, None]
    P = -k3 * np.fft.rfft(np.fft.irfft(D, L, axis=1)[:, :n] ** 3, L, axis=1)
    for _ in range(iters):
        d = np.fft.irfft(D + np.einsum("wst,tw->sw", pre["T"], P), L, axis=1)[:, :n]
        P = -k3 * np.fft.rfft(d ** 3, L, axis=1)
    return P


def distortion_basis(pre):
    """Per story s, the first-order distortion ratio -G b_s F_s / (H U) on case.f,
    F_s = FFT(d_s^3): (n_s, n_ch, n_f) complex (ln H_data - ln H_lin = sum_s k3_s ratio_s)."""
    F = _force(pre, np.ones(pre["D"].shape[0]), 0)[:, pre["keep"]]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.einsum("fcs,sf->scf", pre["G"], F) / pre["Y"][None]
    return np.nan_to_num(ratio, nan=0.0, posinf=0.0, neginf=0.0)


def distortion(pre, k3, iters=ITERATIONS):
    """ln H_data - ln H_lin on case.f (n_ch, n_f) for story springs k3 [N/m^3], with the
    forces' own response fed back `iters` times (a series in k3; 0: first order)."""
    P = _force(pre, k3, iters)[:, pre["keep"]]
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.einsum("fcs,sf->cf", pre["G"], P) / pre["Y"]
    e = np.nan_to_num(e, nan=0.0, posinf=0.0, neginf=0.0)
    return np.log(np.maximum(np.abs(1 + e), 1e-12)) + 1j * np.angle(1 + e)


def estimate(case, problem, z, idx, sigma, steps=GN_STEPS):
    """The joints' k3 per story from the fit at z (problem on points idx with noise sigma).

    k3 by Gauss-Newton on ||r + J dz + Re distortion(k3) / sigma|| with the model's own
    parameters free beside them (dz), the first-order basis as the k3 Jacobian.
    Returns a dict (None when the case has no story-by-story basis): k3 [N/m^3], change
    (24 k3 Var(d) / k per story, the equivalent change between the level and three times
    it), delta_chi2 (the linearised drop against the model's own parameters alone),
    delta_bic, within (all changes within JOINT_CHANGE), accepted and d (the distortion
    on case.f, complex ln)."""
    M, K, C = (np.asarray(a, float) for a in problem.system_matrices(z))   # added DOFs too
    if M.shape[0] > MAX_DOF:
        return None
    groups, B = story_patterns(case.model, M.shape[0])
    if B is None:
        return None
    pre = response_setup(M, C, K, B, case)
    r, J = problem.residuals(z)
    r, J = np.asarray(r, float).ravel(), np.asarray(J, float)
    # the objective's residuals run point by point (every channel of a point together)
    order = _layout(signed(problem, z, case, idx, sigma), r)
    if order is None:
        return None
    ratio = distortion_basis(pre)
    A = np.stack([order(np.real(ratio[s][:, idx]) / sigma) for s in range(B.shape[1])], 1)
    scale = np.maximum(np.linalg.norm(A, axis=0), 1e-300)   # k3 spans decades
    JA = np.hstack([J, A / scale])
    lin = np.linalg.lstsq(J, -r, rcond=1e-10)[0]
    chi_lin = float(np.sum((r + J @ lin) ** 2))
    k3, d = np.zeros(B.shape[1]), np.zeros((len(case.channels), case.f.size), complex)
    for _ in range(steps):
        e = r + order(np.real(d[:, idx]) / sigma)
        k3 = k3 + np.linalg.lstsq(JA, -e, rcond=1e-10)[0][J.shape[1]:] / scale
        d = distortion(pre, k3)
    e = r + order(np.real(d[:, idx]) / sigma)
    chi_nl = float(np.sum((e + J @ np.linalg.lstsq(J, -e, rcond=1e-10)[0]) ** 2))
    # k3's covariance (Gauss-Newton, inflated by the misfit left): the correction's error
    phi = max(1.0, chi_nl / max(r.size - JA.shape[1], 1))
    cov = phi * np.linalg.pinv(JA.T @ JA, rcond=1e-12)[J.shape[1]:, J.shape[1]:]
    cov = cov / np.outer(scale, scale)
    k_story = np.array([_story_stiffness(case.model.K_infl[g], b) for g, b in zip(groups, B.T)])
    change = 24.0 * k3 * pre["var"] / k_story
    drop = chi_lin - chi_nl
    dbic = -drop + B.shape[1] * math.log(max(r.size, 2))
    within = bool(np.all(np.abs(change) <= JOINT_CHANGE))
    return {"k3": k3.tolist(), "change": change.tolist(), "stories": [g + 1 for g in groups],
            "delta_chi2": drop, "delta_bic": dbic, "within": within,
            "accepted": within and dbic < -BIC_ACCEPT, "d": d, "ratio": ratio,
            "cov": cov}


def story_patterns(model, n_dof):
    """(groups, B): each story's spring pattern, +-1 on the DOFs it joins (d = b^T q is the
    story's drift), as the columns of B; (groups, None) unless every stiffness group is
    one story spring."""
    groups, B = story_matrix(model, n_dof)
    if B is None or len(groups) != len(model.K_infl):
        return groups, None
    return groups, B / np.max(np.abs(B), axis=0)


def _layout(sg, r):
    """How an (n_ch, n) array is flattened in the objective's residual vector r (checked
    on the signed residuals sg); None when neither order matches."""
    for order in (lambda a: a.T.ravel(), lambda a: a.ravel()):
        if sg.size == r.size and np.allclose(order(sg), r, rtol=1e-6, atol=1e-9):
            return order
    return None


def _story_stiffness(K_s, b):
    """The nominal spring k_s of a story whose matrix is K_s = k_s b b^T (b of +-1)."""
    K_s = K_s.toarray() if hasattr(K_s, "toarray") else np.asarray(K_s, float)
    b = b[:K_s.shape[0]]
    return float(b @ K_s @ b) / float(b @ b) ** 2


def corrected(case, est):
    """The case with its data divided by exp(the estimated distortion): the frame's linear
    FRF."""
    d = est["d"]
    # the series holds where the distortion is small, and it is estimated on the band
    band = case.f[case.selected]
    out = (case.f < band.min())[None, :] | (case.f > band.max())[None, :]
    beyond = (np.abs(d) > MAX_LN) & ~out
    used = np.where(out | beyond, 0.0, d)
    H = case.H * np.exp(-used)
    # the correction's own error counts as noise: k3's covariance carried through the
    # first-order basis, and REL_ERROR of what it removed (the series' own); where the
    # series cannot reach, the point says nothing of the linear FRF (the whole distortion)
    ratio, cov = est["ratio"], np.asarray(est["cov"])
    var_re, var_im = (np.einsum("scf,st,tcf->cf", part(ratio), cov, part(ratio))
                      for part in (np.real, np.imag))
    rel = (REL_ERROR * np.abs(used)) ** 2

    def wider(s, var):
        if s is None:
            return None
        return np.where(beyond, np.hypot(s, np.abs(d)),
                        np.sqrt(s ** 2 + rel + np.where(out, 0.0, np.abs(var))))

    nm = case.noise
    noise = replace(nm, sigma_ln=wider(nm.sigma_ln, var_re),
                    sigma_phase=wider(nm.sigma_phase, var_im),
                    sigma_detect=wider(nm.sigma_detect, var_re))
    target = replace(case.target, H=H[:, case.selected])
    public = {k: v for k, v in est.items() if k not in ("d", "ratio", "cov")}
    public["k3_se"] = np.sqrt(np.clip(np.diag(cov), 0, None)).tolist()
    public["largest_ln_change"] = float(np.max(np.abs(np.real(used))))
    public["points_beyond"] = int(beyond.sum())
    return replace(case, H=H, target=target, noise=noise, sweep_joints=public,
                   measured=(case.H, case.target, case.noise))


def sweep_stage(case, points, base, log, refit):
    """(case, points, baseline): the case with the joints' distortion divided out of its
    data as measured (estimated from the baseline at hand), the points' noise, target and
    problem on it and the baseline refitted by refit(case, points, z); unchanged when the
    data are left as they are (another route, no story basis, a distortion not proven, or
    a level dependence beyond the joints' band)."""
    if not applies(case):
        return case, points, base
    m = as_measured(case)
    est = logged_step("sweep joints", fingerprint(points.fit, base.res.z, len(case.released_gains)),
                      lambda lg: _estimated(m, points, base.res.z, lg), log)
    if est is None or not est["accepted"]:
        return case, points, base
    c = corrected(m, est)
    p = _on(c, points)
    b = replace(refit(c, p, base.res.z), before=base.before)
    if not windows_explained(b.chi, b.nu):
        # the bend is not all the misfit: a missing effect shapes it too, and k3 fitted
        # beside it take up part of it (a coupling's misfit read as joints of -2 %)
        log("sweep: the joints' bend leaves the baseline unexplained (reduced chi-square "
            f"{b.chi / b.nu:.3g}): the data are kept as measured; the bend is estimated "
            "again in the final model")
        return case, points, base
    chi2 = [float(base.chi / base.nu), float(b.chi / b.nu)]
    return replace(c, sweep_joints={**c.sweep_joints, "reduced_chi2": chi2}), p, b


def as_measured(case):
    """The case with its data as measured (no joints' correction)."""
    if case.measured is None:
        return case
    H, target, noise = case.measured
    return replace(case, H=H, target=target, noise=noise, sweep_joints=None, measured=None)


def final_sweep(case, points, base, state, log, refit):
    """(case, points, baseline, state) with the joints' bend estimated in the final model
    (state: its enrichments and z) from the data as measured. Corrected at the baseline: the
    correction is kept and sweep_joints says whether the final model confirms it. Not
    corrected there (the bend was not all of the baseline's misfit): when the final model
    proves it within the joints' band, it is divided out now and the baseline and the
    final model are refitted on the corrected data."""
    if not applies(case):
        return case, points, base, state
    est = logged_step("sweep joints, final model", fingerprint(points.fit, state["z"]),
                      lambda lg: _estimated(as_measured(case), points, state["z"], lg,
                                            state["current"], "in the final model"), log)
    ok = bool(est and est["accepted"])
    final = None if est is None else {k: est[k] for k in ("k3", "change", "delta_bic")}
    if case.sweep_joints:
        if not ok:
            log("sweep: with the findings in the model the joints' bend is not proven: the "
                "correction made before them may hold part of what they explain")
        return (replace(case, sweep_joints={**case.sweep_joints, "confirmed": ok,
                                            "final": final}), points, base, state)
    if not ok:
        return case, points, base, state
    c = corrected(case, est)
    p = _on(c, points)
    b = replace(refit(c, p, base.res.z), before=base.before)
    pr = diagnosis_problem(c, p.target, list(state["current"]), optimize=False)
    res = best_fit(pr, [state["z"]])
    held = float(np.mean(normalised(pr, res.z, c, p.held, p.sig_held) ** 2))
    chi2 = [float(state["chi"] / base.nu), float(2 * res.f / base.nu)]
    c = replace(c, sweep_joints={**c.sweep_joints, "reduced_chi2": chi2, "confirmed": True,
                                 "final": final, "after_findings": True})
    return c, p, b, {"current": state["current"], "z": res.z, "chi": 2 * res.f, "held": held,
                     "problem": pr}


def _on(case, points):
    """The points' noise, target and problem on the case's (corrected) data."""
    sig_fit, sig_held = noise_sigma(case, points.fit), noise_sigma(case, points.held)
    target = fit_target(case, points.fit, sig_fit)
    return replace(points, sig_fit=sig_fit, sig_held=sig_held, target=target,
                   base=diagnosis_problem(case, target))


def _estimated(case, points, z, log, current=(), where=""):
    # the fitted windows and their held-out shoulders: the bend's shape lies in both
    idx = np.sort(np.concatenate([points.fit, points.held]))
    sig = noise_sigma(case, idx)
    problem = diagnosis_problem(case, fit_target(case, idx, sig), list(current), compile=False)
    est = estimate(case, problem, z, idx, sig)
    if est is not None:
        log(f"sweep: the joints' distortion of the one-segment record{' ' * bool(where)}{where}, "
            "per story change between this level and three times it: "
            + ", ".join(f"{100 * c:+.2f} %" for c in est["change"])
            + f" (chi-square drop {est['delta_chi2']:.1f}, dBIC {est['delta_bic']:.1f}; "
            + (("confirmed" if where else "removed from the data") if est["accepted"] else
               "beyond the joints' band: left in the data" if not est["within"] else
               "not proven: left in the data") + ")")
    return est


def carried(first):
    """What a later look takes from the first look's case: its corrected data."""
    if first.sweep_joints is None:
        return {}
    return {"H": first.H, "target": first.target, "noise": first.noise,
            "sweep_joints": first.sweep_joints, "measured": first.measured}
