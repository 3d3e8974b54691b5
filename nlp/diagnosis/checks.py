"""Checks of the final model beyond the fitted windows: phase, loss, the whole band.

* phase_check - sensor delays from the phase the log-magnitude fit did not use;
* loss_check - hysteretic loss from magnitude and phase together, off the windows;
* whole_band - the residual map over every coherently measured frequency, the
  resonances the model lacks (extra modes) and the largest misfits (hot spots).
"""

import numpy as np

from nlp.case.selection import detection_form
from nlp.diagnosis.band import (MAX_SCATTER, band_map, band_mask, extra_modes, hot_spots,
                                local_sigma, near)
from nlp.diagnosis.families import HystereticDamping, SensorDelay
from nlp.diagnosis.fitting import (diagnosis_problem, fit_target, fit_windows, noise_sigma,
                                   quasi_se, with_values)
from nlp.diagnosis.loss import band_points, loss_decision, loss_row
from nlp.diagnosis.phase import MIN_PHASE, delay_check
from nlp.diagnosis.refit import REFIT_ITER
from nlp.diagnosis.resolution import case_resolution
from nlp.diagnosis.locations import story_count
from nlp.frf.scatter import second_difference_factor

MIN_LOSS_POINTS = 20   # band points below which the loss check is not made
# above fs / ANTI_ALIAS the acquisition's anti-alias filter shapes the spectra
ANTI_ALIAS = 2.56
NULL_RESTARTS = 3    # the loss check's null refit: at most 4 x REFIT_ITER iterations


def phase_check(case, state, idx, log):
    """Sensor delays from the phase residual of the final model (nlp/diagnosis/phase.py),
    when the FRFs have a phase that the fit did not use (log-magnitude residual)."""
    if (not case.has_phase or case.config.objective.residual == "complex"
            or getattr(case, "noise", None) is None):
        return None
    Ha = state["problem"].channel_frfs(state["z"], 2 * np.pi * case.f[idx])
    out = delay_check(case.f[idx], case.H[:, idx], Ha, case.noise.sigma_phase[:, idx],
                      [c.name for c in case.channels], [c.sensor_name for c in case.channels])
    for f in out["findings"]:
        log("  phase: " + f["statement"])
    return out


def _delay_enrichments(case, delays):
    """SensorDelay enrichments and start values [ms] of the delay findings (a late input
    makes every output channel lead by its delay)."""
    out = []
    for d in delays:
        ch = d["location"]["channel"]
        tau = next(iter(d["parameters"].values()))
        # one enrichment per sensor: a jointly fitted sensor's delay acts on all its channels
        chans = (list(dict.fromkeys(c.sensor_name for c in case.channels)) if ch == "input"
                 else [ch])
        out += [(SensorDelay(c), [-tau if ch == "input" else tau]) for c in chans]
    return out


def _delay_nuisance(case, phase):
    """SensorDelay enrichments and starts [ms]: the delays stage 8 named, and every other
    sensor's delay whose phase at the top of the band reaches MIN_PHASE, the phase error a
    magnitude fit leaves anyway. An acquisition chain's delay (an anti-alias filter's group
    delay reads as one) shifts the phase a loss is judged on, named or not: on lab
    development cases (seed 12) the accelerometers' chains lagged the input's by about 9 ms
    (0.8 rad at the top of the band), none named since they agreed with each other, and the
    loss refit without them stood at 1,800x the noise. Below MIN_PHASE a "delay" is as likely
    the loss's own phase (on the blind benchmark, story losses of 0.02 read as 0.4-1.2 ms)."""
    if not phase:
        return []
    out = _delay_enrichments(case, phase["findings"])
    have = {e.channel for e, _ in out}
    for r in phase["channels"]:
        tau = float(r["delay_ms"])
        if (r["channel"] not in have and np.isfinite(tau)
                and abs(tau) * 1e-3 * r["omega_max"] >= MIN_PHASE):
            out.append((SensorDelay(r["channel"]), [tau]))
    return out


def loss_check(case, state, phase, log):
    """Hysteretic loss from magnitude and phase together (nlp/diagnosis/loss.py): the final
    model refitted with the complex residual over the coherently measured band off the
    half-power windows, without and with a loss eta K (whole frame) or eta K_s (each story); every
    sensor's delay that matters (phase: the phase check's result; _delay_nuisance) is refitted
    alongside. Only for a log-magnitude diagnosis of FRFs with a
    phase: a complex diagnosis already weighs the loss candidates with their phase."""
    cfg = case.config
    if (not case.has_phase or cfg.objective.residual == "complex"
            or getattr(case, "noise", None) is None
            or any(e.family == "hysteretic_damping" for e in state["current"])):
        return None
    fc = cfg.frequencies
    idx = band_points(case.f, band_mask(case.f, case.coherence, fc.fmin, fc.min_coherence),
                      case.noise.sigma_phase, fc.fmax, exclude=fit_windows(cfg, case, 1))
    if idx.size < MIN_LOSS_POINTS:
        return None
    # the complex residual (H_a - H_x) / |H_x| has the scatter of ln|H| in each part
    target = fit_target(case, idx, noise_sigma(case, idx))
    dl = _delay_nuisance(case, phase)
    current = list(state["current"]) + [e for e, _ in dl]
    starts = [v for _, v in dl]

    # one problem holds every location's loss (eta K, eta K_1 ... eta K_n, last); the
    # nested fits hold the other locations at zero by their bounds: one build, n + 2 solves
    losses = [HystereticDamping()] + [HystereticDamping(s)
                                      for s in range(1, story_count(case.model) + 1)]
    m = len(losses)
    pr = diagnosis_problem(case, target, current + losses, optimize=False, max_iter=REFIT_ITER,
                           residual="complex")
    lo, hi = pr.bounds
    held_lo, held_hi = lo.copy(), hi.copy()
    held_lo[-m:] = held_hi[-m:] = 0.0          # z = 0 is eta = 0 (theta = scale z)
    z0 = with_values(pr, state["z"], [x for v in starts for x in v] + [0.0] * m)
    r0 = pr.solve(z0, bounds=(held_lo, held_hi))
    # the null refit is continued from where the cap stopped it: capped once, it stopped
    # unconverged on 8 of 9 lab development cases (seed 12) and no loss was judged; uncapped,
    # a location's refit of a 5-storey null ran past 40 minutes (its cap now bounds it)
    for _ in range(NULL_RESTARTS):
        if r0.success:
            break
        again = pr.solve(r0.z, bounds=(held_lo, held_hi))
        r0 = again if again.success or again.f < r0.f else r0
    if not r0.success:
        log(f"  loss check: the complex refit of the final model did not converge "
            f"({r0.status}); no hysteretic loss is judged")
        return {"rows": [], "findings": [], "points": int(idx.size), "converged": False}
    n_res = pr.n_used
    rows = []
    for j, e in enumerate(losses):
        i = pr.params.n_z - m + j
        b_hi = held_hi.copy()
        b_hi[i] = hi[i]
        free = np.ones(pr.params.n_z, bool)
        free[-m:] = False
        free[i] = True
        zs = r0.z.copy()
        zs[i] = 0.5                                # eta = half its scale: inside the box
        r1 = pr.solve(zs, bounds=(held_lo, b_hi))
        if not np.isfinite(r1.f) or r1.f > r0.f:   # no better than without: the null
            z1, chi, conv = r0.z, 2 * r0.f, bool(r0.success)
        else:
            z1, chi, conv = r1.z, 2 * r1.f, bool(r1.success)
        eta = float(pr.theta(z1)[pr.params.n_theta - m + j])
        se = float(quasi_se(pr, z1, free)[0][pr.params.n_theta - m + j])
        rows.append({**loss_row(e.location, eta, se, chi, 2 * r0.f, n_res, int(free.sum()),
                                conv), "name": e.names[0]})
    best, ties = loss_decision(rows)
    findings = [] if best is None else [_loss_finding(best, ties)]
    for f in findings:
        log("  loss: " + f["statement"])
    return {"rows": rows, "findings": findings, "points": int(idx.size), "converged": True,
            "chi2_null": 2 * r0.f, "residuals": int(n_res)}


def _loss_finding(best, ties):
    where = ("the whole frame (eta K)" if not best["location"]
             else f"story {best['location']['between'][1]} (eta K_s)")
    name = best["name"]
    text = (f"A frequency-independent (hysteretic) loss on {where}: eta = {best['eta']:.3g} +- "
            f"{best['standard_error']:.2g}. A viscous C matches it at every resonance, so the "
            f"magnitudes cannot tell; the phase off resonance can (scaled dBIC "
            f"{best['delta_bic']:.1f} on magnitude and phase over the band).")
    if ties:
        text += (" Where it acts cannot be told apart from: "
                 + "; ".join(f"{'the whole frame' if not t['location'] else 'story %d' % t['location']['between'][1]}"
                             f" (dBIC {t['delta_bic']:.1f})" for t in ties) + ".")
    return {"physics": "hysteretic_damping", "location": best["location"],
            "parameters": {name: best["eta"]}, "uncertainty": {name: best["standard_error"]},
            "evidence": {"source": "phase", "delta_bic": best["delta_bic"],
                         "phi": best["phi"], "explained": best["explained"],
                         "indistinguishable_locations": [t["location"] for t in ties]},
            "statement": text}


def whole_band(case, base, zb, improved, zi, fit):
    """Residual map over every coherently measured frequency and the extra modes."""
    fc = case.config.frequencies
    mask = band_mask(case.f, case.coherence, fc.fmin, fc.min_coherence)
    rec = getattr(case, "records", None)
    if rec is not None and getattr(rec, "fs", None):
        # above fs / 2.56 the acquisition's anti-alias filter shapes the spectra: an
        # analyzer's usable band ends there, and a roll-off is no resonance
        mask = mask & (case.f <= rec.fs / ANTI_ALIAS)[None, :]
    idx = np.nonzero(mask.any(axis=0))[0]
    if idx.size < 5:
        return None
    f = case.f[idx]
    ex = case.target.excitation

    def ln_det(H):
        return np.log(np.abs(detection_form(f, H, case.channels, ex)) + 1e-300)

    Lx = ln_det(case.H[:, idx])
    d2f = second_difference_factor(case.config.data.window)   # windowed estimates: bins correlate
    sig = local_sigma(Lx, d2_factor=d2f)
    m = np.broadcast_to(mask[:, idx], Lx.shape) & (sig < MAX_SCATTER)  # no coherent data there
    if getattr(case, "noise", None) is not None:
        # nor where the route's own noise model says the estimate is noise
        m = m & (case.noise.detect[:, idx] < MAX_SCATTER)
    fit_local = np.nonzero(np.isin(idx, fit))[0]
    maps = {}
    for key, pr, z in (("before", base, zb), ("after", improved, zi)):
        La = ln_det(pr.channel_frfs(z, 2 * np.pi * f))
        r = (Lx - La) / sig
        cells = band_map(f, r, m, fit_local)
        for c in cells:
            c["channel"] = case.channels[c["channel"]].name
        maps[key] = cells
    res_hz = case_resolution(case)
    extra = extra_modes(f, Lx, La, sig, m, d2_factor=d2f, resolution=res_hz)
    # a resonance kept as model discrepancy is in the model, though its real residue may
    # leave a channel's peak standing: it is reported there, not again as an extra mode
    extra = [e for e in extra if not any(near(e["frequency_hz"], d.f0, res_hz)
                                         for d in case.discrepancy)]
    for e in extra:
        e["channels"] = [case.channels[c].name for c in e["channels"]]
        e["strongest"] = case.channels[e["strongest"]].name
    used = m.any(axis=0)
    return {"band_hz": [float(f[used].min()), float(f[used].max())] if used.any() else None,
            "map": maps, "extra_modes": extra, "hot_spots_hz": hot_spots(f, r, m, fit_local)}


def unexplained(case, pr, z, fit):
    """Frequencies [Hz] the model (pr at z) does not explain: the measured resonances it
    lacks, and the largest misfits off the fitted points (band.hot_spots)."""
    whole = whole_band(case, pr, z, pr, z, fit)
    if not whole:
        return (), ()
    return tuple(e["frequency_hz"] for e in whole["extra_modes"]), tuple(whole["hot_spots_hz"])
