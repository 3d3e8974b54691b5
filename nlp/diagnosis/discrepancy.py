"""Model discrepancy: resonances outside the model class, named and kept in every fit.

A planar shear model of a real frame lacks its out-of-plane, torsional and local modes.
Left out, their misfit is taken up by whichever candidate family absorbs most of it (a
sensor gain soaks up a mode's tail on one channel), and every candidate competes with
that misfit instead of with the noise. Here each resonance the baseline lacks
(:func:`nlp.diagnosis.band.extra_modes`) is first offered to the catalogue families that
add a resonance of their own (an appendage at each floor, a flexible base). A family
explains it when fitting the family instead of a free modal term
(:class:`nlp.diagnosis.families.ExtraMode`: frequency, damping and one residue per
channel) costs no more than a chi-square test of the restriction allows: the family's
resonance is then the physics the modal term describes with fewer, physical parameters,
and the candidate search is left to name it. A resonance no family explains is model
discrepancy: its modal term stays in every later fit (Case.discrepancy), so candidates
are judged against the data with it present, and it is reported as what it is, with the
channels that see it. This is the "embedded" treatment of model error (the discrepancy
is a parametric term inside the model, fitted with it; Kennedy & O'Hagan, J. R. Stat.
Soc. B 63, 2001, treat it as a Gaussian process outside), in the form modal updating
uses for residual modes (Ewins, Modal Testing, 2000, ch. 5.3).
"""

from dataclasses import replace

import numpy as np
from scipy.linalg import eigh
from scipy.signal import find_peaks
from scipy.stats import chi2 as chi2_dist

from nlp.diagnosis.widen import HOT_WINDOW
from nlp.case.selection import detection_form, selectable
from nlp.diagnosis.band import MIN_EXCESS, PEAK_Z, local_sigma, near
from nlp.diagnosis.checks import whole_band
from nlp.diagnosis.decide import where
from nlp.diagnosis.evidence import SIGNIFICANCE, dispersion
from nlp.diagnosis.families import BaseFlexibility, ExtraMode, SecondaryOscillator
from nlp.diagnosis.fitting import best_fit, diagnosis_problem, quasi_se
from nlp.diagnosis.candidates import base_candidate
from nlp.diagnosis.locations import floor_count
from nlp.diagnosis.refit import refit
from nlp.diagnosis.resolution import case_resolution, damping_pinned, resolved
from nlp.frf.forms import POWER
from nlp.frf.freqsel import MATCH_RATIO

__all__ = ["RESTRICTION_LEVEL", "extra_modes_in_band", "resonant", "kept_modes",
           "own_modes_in_band", "outside_class", "class_statement", "beyond_band", "EDGE_MARGIN", "fit_discrepancy", "explained_by",
           "described", "subset_z", "LEVEL_HALF_WIDTH"]

# The restriction "a catalogue family instead of a free modal term" is refused when its
# chi-square rise (scaled by the dispersion) exceeds the 99 % point of a chi-square with
# as many degrees of freedom as the family has fewer parameters: a 1 % test, so a true
# appendage is taken for model error once in a hundred.
RESTRICTION_LEVEL = 0.99
LEVEL_HALF_WIDTH = 0.01   # L_c: median |H_x| within +-1 % of the resonance
# A modal term is fitted only where the band holds both flanks of its peak: +-3 % is some
# six half-power widths of a mode damped at 0.25 %, and about one at 1.5 %.
EDGE_MARGIN = 0.03


def extra_modes_in_band(case, points, base):
    """ExtraMode terms for the resonances the baseline lacks inside the fitted band (where
    the fit can measure them) that are not its own modes shifted (:func:`shifted`)."""
    whole = whole_band(case, points.base, base.res.z, points.base, base.res.z, points.fit)
    if not whole:
        return []
    ok = selectable(case.config, case.f, case.channels, case.coherence)
    fsel = case.f[ok]
    if fsel.size == 0:
        return []
    out, peaks = [], measured_peaks(case)
    res_hz = case_resolution(case)
    for e in whole["extra_modes"]:
        f0 = float(e["frequency_hz"])
        # a resonance is a peak of the measurement; a step or dip against the model (a
        # moved anti-resonance) is not one
        if (_fittable(f0, fsel)
                and peaks.size and np.any(near(peaks, f0, res_hz))
                and not shifted(case, points.base, base.res.z, f0, peaks)):
            out.append(extra_mode(case, f0))
    return out


def _fittable(f0, fsel):
    """Whether the fitted band holds both flanks of a resonance at f0 [Hz]."""
    return fsel.min() < f0 * (1 - EDGE_MARGIN) and f0 * (1 + EDGE_MARGIN) < fsel.max()


def beyond_band(case, pr, z, extra):
    """(extra modes, model discrepancy beyond the fitted band) from the whole band's extra
    modes (:func:`nlp.diagnosis.checks.whole_band`) of the model pr at z.

    A resonance the model lacks where the fitted band cannot hold it (beyond fmin or fmax,
    or within EDGE_MARGIN of them) cannot be fitted as a modal term, yet the data show it on
    named channels. Unless it is one of the model's own modes moved (:func:`shifted`), the
    model class cannot have it: it is model discrepancy, reported with its channels and not
    fitted. Its in-band effect is the tail of a mode outside the band (residual
    flexibility), which the fit leaves in the misfit."""
    ok = selectable(case.config, case.f, case.channels, case.coherence)
    fsel = case.f[ok]
    if fsel.size == 0 or not extra:
        return list(extra), []
    keep, out, peaks = [], [], measured_peaks(case)
    for e in extra:
        f0 = float(e["frequency_hz"])
        if _fittable(f0, fsel) or shifted(case, pr, z, f0, peaks):
            keep.append(e)
            continue
        side = "above" if f0 > fsel.max() * (1 - EDGE_MARGIN) else "below"
        band = f"{fsel.min():.1f}-{fsel.max():.1f} Hz"
        seen = list(dict.fromkeys(list(e["channels"]) + peak_channels(case, f0)))
        out.append({"physics": "model_discrepancy", "frequency_hz": f0, "channels": seen,
                    "fitted": False, "band_hz": [float(fsel.min()), float(fsel.max())],
                    "statement": (f"A resonance at {f0:.2f} Hz, {side} the fitted band "
                                  f"({band}), seen by {', '.join(seen)}, that the model does not "
                                  "have and the model class cannot have (an out-of-plane, "
                                  "torsional or local mode, or a subsystem outside the model): "
                                  "model discrepancy, reported and not fitted (widen the band "
                                  "to fit it).")})
    return keep, out


def _ln_accelerance(case):
    """ln|H| of every channel as an accelerance (every mode peaks there): (n_ch, n_f)."""
    return np.log(np.abs(detection_form(case.f, case.H, case.channels, case.target.excitation))
                  + 1e-300)


def measured_peaks(case):
    """Frequencies [Hz] of the measured resonances: peaks of any channel's accelerance
    rising ln 1.2 above their surroundings (band.MIN_EXCESS)."""
    D = _ln_accelerance(case)
    out = set()
    for c in range(D.shape[0]):
        pk, _ = find_peaks(D[c], prominence=MIN_EXCESS, wlen=41)
        out.update(case.f[pk].tolist())
    return np.array(sorted(out))


def peak_channels(case, f0):
    """Names of the channels whose accelerance peaks near f0 [Hz] (band.near), rising
    above its surroundings by max(ln 1.2, PEAK_Z x the channel's median local noise). The
    median over the band, not the local value: a strong, sharp peak inflates the local
    scatter around itself on the channels that see it best."""
    D = _ln_accelerance(case)
    sig = np.median(local_sigma(D), axis=1)
    res_hz = case_resolution(case)
    out = []
    for c in range(D.shape[0]):
        pk, props = find_peaks(D[c], prominence=MIN_EXCESS, wlen=41)
        close = near(case.f[pk], f0, res_hz)
        if np.any(props["prominences"][close] >= max(MIN_EXCESS, PEAK_Z * sig[c])):
            out.append(case.channels[c].name)
    return out


def natural_frequencies(pr, z):
    """Undamped natural frequencies [Hz] of the model pr at z."""
    M, K, _ = pr.system_matrices(z)
    return np.sqrt(np.abs(eigh(np.asarray(K, float), np.asarray(M, float),
                               eigvals_only=True))) / (2 * np.pi)


def shifted(case, pr, z, f0, peaks):
    """Whether a resonance at f0 [Hz] the model lacks is one of the model's own modes moved:
    a mode of the updated model within MATCH_RATIO of f0 shows no measured peak, other than
    f0's own, within NEAR_MODEL or the estimate's resolution of it (band.near). A missing
    coupling or a mistuned storey moves a mode; the data then show a peak the model lacks
    and lack the model's, one mode, not an extra one. An
    appendage tuned near a mode splits it the same way; it is left to the candidates.
    peaks: the measured resonances [Hz] (:func:`measured_peaks`)."""
    return moved(natural_frequencies(pr, z), f0, peaks, case_resolution(case))


def moved(f_r, f0, peaks, resolution):
    """Whether one of the model's natural frequencies f_r [Hz] within MATCH_RATIO of f0
    has no measured peak (peaks [Hz]) near it (band.near) other than f0's own: peaks within
    the resolution [Hz] of f0 are f0's, read a bin apart on other channels."""
    f_r, peaks = np.asarray(f_r, float), np.asarray(peaks, float)
    close = f_r[np.abs(np.log(f_r / f0)) < np.log(MATCH_RATIO)]
    others = peaks[~near(peaks, f0, resolution)]
    return any(others.size == 0 or not np.any(near(others, fr, resolution)) for fr in close)


def extra_mode(case, f0):
    """The ExtraMode term at f0 [Hz] on every channel of case."""
    near = np.abs(case.f / f0 - 1.0) <= LEVEL_HALF_WIDTH
    levels = tuple(float(np.median(np.abs(case.H[c, near]))) for c in range(len(case.channels)))
    return ExtraMode(f0, tuple(ch.name for ch in case.channels),
                     tuple(POWER[ch.output] for ch in case.channels), levels)


def _residue_starts(case, pr0, z0, e, idx):
    """Start residues a_c of mode e: the least-squares projection of the baseline's complex
    misfit on the term's shape at f0 with zeta_x = 0.01 (magnitudes when there is no phase),
    and the same with every sign flipped."""
    w = 2 * np.pi * case.f[idx]
    Ha = pr0.channel_frfs(z0, w)
    wx = 2 * np.pi * e.f0
    g = wx ** 2 / (wx ** 2 - w ** 2 + 2j * 0.01 * wx * w)
    a = []
    for c in range(len(e.channels)):
        shape = e.levels[c] * g * (1j * w / wx) ** e.powers[c]
        d = case.H[c, idx] - Ha[c] if case.has_phase else np.abs(case.H[c, idx]) - np.abs(Ha[c])
        s = shape if case.has_phase else np.abs(shape)
        a.append(float(np.clip(np.real(np.vdot(s, d)) / max(np.vdot(s, s).real, 1e-300), -0.9, 0.9)))
    return a


def fit_discrepancy(case, pr0, z_base, modes, idx):
    """The case's model plus every mode's term, fitted from the baseline's optimum z_base:
    (problem, result). pr0: the case's own model on the target; idx: the fitted points (for
    the residues' starts)."""
    target = pr0.target
    starts_a = [_residue_starts(case, pr0, z_base, e, idx) for e in modes]
    c_d = replace(case, discrepancy=tuple(modes))
    pr = diagnosis_problem(c_d, target, optimize=False)
    zs = []
    for sign in (1.0, -1.0):
        for zeta in (0.01, 0.003):
            theta = pr.theta(np.concatenate([z_base, np.zeros(pr.params.n_z - z_base.size)]))
            vals = [v for e, a in zip(modes, starts_a)
                    for v in [e.f0, zeta] + [sign * x for x in a]]
            theta[-len(vals):] = vals
            zs.append(pr.params.z_from_theta(theta))
    return pr, best_fit(pr, zs)


def resonant(pr, z, modes):
    """The modes whose fitted damping the data measure: not within one standard error of
    its lower bound (nlp.diagnosis.resolution.damping_pinned, the appendage's rule). A term
    pinned there asks for a line as sharp as the model allows: an excursion a bin or two
    wide, not a resonance the model class lacks. pr, z: the model with every mode fitted."""
    theta, se = pr.theta(z), quasi_se(pr, z)[0]
    names = pr.params.names
    out = []
    for m in modes:
        i = names.index(m.names[1])
        if not damping_pinned(float(theta[i]), float(se[i]), m.spec({})["lower"][1]):
            out.append(m)
    return out


def own_modes_in_band(case, pr, z):
    """Natural frequencies [Hz] of the model pr at z inside the case's selectable band."""
    ok = selectable(case.config, case.f, case.channels, case.coherence)
    fsel = case.f[ok]
    f_r = natural_frequencies(pr, z)
    return f_r[(f_r >= fsel.min()) & (f_r <= fsel.max())] if fsel.size else f_r[:0]


def outside_class(n_missing, n_own):
    """Whether the model lacks a class of motion, not a subsystem: as many resonances in its
    band as it has there. A subsystem (an appendage, a flexible base, the table) adds one
    resonance; the out-of-plane or torsional motion of an n-storey frame adds n, one per
    storey, as many as the planar model's own. Catalogue families fitted to such a model take
    up that motion's coupling to the model's modes, which each missing mode the sensors see
    has, so no change of the model's parameters is named (docs/method/diagnosis.md)."""
    return n_own > 0 and n_missing >= n_own


def distinct_count(pr, z, modes):
    """How many separate resonances the fitted terms of modes are: two whose half-power
    bands overlap (separation under zeta_a f_a + zeta_b f_b, resolution.resolved) are one
    peak seen twice (one mode read on different channels), not two modes. pr, z: the
    model with every mode fitted."""
    theta, names = pr.theta(z), list(pr.params.names)
    fz = sorted((float(theta[names.index(m.names[0])]), float(theta[names.index(m.names[1])]))
                for m in modes)
    count, last = 0, None
    for f, zeta in fz:
        if last is None or resolved(f - last[0], zeta * f + last[1] * last[0], 0.0):
            count += 1
            last = (f, zeta)
    return count


def kept_modes(case, wide, pr_d, res_d, modes, n_fit, log, spent=lambda: False, n_own=None):
    """The modes kept as model discrepancy: resonant (their damping measured) and explained
    by no catalogue family as well as by a free modal term. wide: the look's points (target,
    held-out points and their noise); pr_d, res_d: the model with every mode fitted.
    spent() true: the time budget is spent, and the modes left are kept untested (no
    family is claimed for them). n_own: the model's own modes in the band; when the
    resonant modes are as many (:func:`outside_class`), every one is kept and no family is
    asked. Returns (kept, untested, outside)."""
    keep, untested = [], []
    measured = resonant(pr_d, res_d.z, modes)
    for m in modes:
        if not any(m is x for x in measured):
            log(f"  {m.f0:.2f} Hz: its damping sits at the bound of its box: a line a bin or "
                "two wide, not a resonance; not model discrepancy")
    n_missing = distinct_count(pr_d, res_d.z, measured) if measured and n_own else 0
    if n_own is not None and outside_class(n_missing, n_own):
        log(f"  {n_missing} resonances the model lacks against its own {n_own} in the "
            "band: a class of motion outside the model (out-of-plane, torsional), not a "
            "subsystem; all kept as model discrepancy, and no change of the model is named")
        return list(measured), [], True
    for m in measured:
        if spent():
            keep.append(m)
            untested.append(m.f0)
            log(f"  {m.f0:.2f} Hz: the time budget is spent: kept as model discrepancy without "
                "asking the families")
            continue
        alts = explained_by(case, wide.target, pr_d, res_d, modes, m, n_fit, wide.held,
                            wide.sig_held)
        if alts:
            r = alts[0]["restriction"]
            log(f"  {m.f0:.2f} Hz: {where(alts[0])} explains it as "
                f"well as a free modal term (scaled chi-square rise {r['scaled_rise']:.1f}, "
                f"limit {r['limit']:.1f}): left to the candidate search")
        else:
            keep.append(m)
            log(f"  {m.f0:.2f} Hz: no catalogue family explains it as well as a free modal "
                "term: model discrepancy, kept in every fit")
    return keep, untested, False


def kept_discrepancy(case, wide, z_base, modes, log, spent=lambda: False, n_own=None):
    """(indices of the modes kept as model discrepancy, the optimum of the model with
    them or None, the frequencies kept untested because spent() said the time budget was
    spent, whether the model lacks a class of motion (:func:`outside_class`)) on the look's
    points with windows at the modes (wide), from the baseline's optimum z_base. n_own: the
    model's own modes in the band."""
    b0 = best_fit(wide.base, [z_base])
    pr_d, res_d = fit_discrepancy(case, wide.base, b0.z, modes, wide.fit)
    n_fit = wide.base.n_used
    log(f"  with a free modal term at each: chi-square {2 * res_d.f:.1f} against "
        f"{2 * b0.f:.1f} without, on {n_fit} fitted points")
    keep, untested, outside = kept_modes(case, wide, pr_d, res_d, modes, n_fit, log, spent,
                                         n_own)
    kept = [i for i, m in enumerate(modes) if any(m is k for k in keep)]
    return (kept, (subset_z(pr_d, res_d.z, modes, keep) if keep else None), untested,
            outside)


def subset_z(pr, z, modes, keep):
    """Decision vector of the model with only the modes in keep (z: with all modes)."""
    n_base = pr.params.n_z - sum(len(m.names) for m in modes)
    parts, k = [z[:n_base]], n_base
    for m in modes:
        if any(m is x for x in keep):
            parts.append(z[k:k + len(m.names)])
        k += len(m.names)
    return np.concatenate(parts)


def explained_by(case, target, pr_d, res_d, modes, e, n_fit, held, sig_held, box=False):
    """The catalogue refit (appendage at a floor, flexible base) that explains the resonance
    of mode e as well as its free modal term (module docstring), best first; [] when none.
    pr_d, res_d: the model with every mode fitted. The appendages start tuned to e alone
    (box=True adds refit's two starts spread over their box, which answer another question:
    an appendage tuned elsewhere that takes up other misfit)."""
    others = tuple(m for m in modes if m is not e)
    c_e = replace(case, discrepancy=others)
    z_cur = subset_z(pr_d, res_d.z, modes, others)
    chi_d = 2 * res_d.f
    phi = dispersion(chi_d, n_fit - pr_d.params.n_z)
    cands = [SecondaryOscillator(p, f0=e.f0, resonances=(e.f0,))
             for p in range(1, floor_count(case) + 1)] + ([BaseFlexibility()] if base_candidate(case) else [])
    out = []
    for cand in cands:
        r = refit(c_e, target, [], z_cur, cand, 0.0, n_fit, held, sig_held, box=box)
        dof = max(len(e.names) - len(cand.names), 1)
        rise = (r["chi2"] - chi_d) / phi
        r["restriction"] = {"scaled_rise": float(rise), "dof": dof,
                            "limit": float(chi2_dist.ppf(RESTRICTION_LEVEL, dof))}
        if rise <= r["restriction"]["limit"]:
            r["problem"] = None
            out.append(r)
    return sorted(out, key=lambda r: r["chi2"])


def described(pr, z, modes):
    """Each mode's fitted frequency, damping and residues with quasi-likelihood errors, and
    the channels that see it (a residue more than SIGNIFICANCE errors from zero)."""
    theta = pr.theta(z)
    se = quasi_se(pr, z)[0]
    names = list(pr.params.names)
    out = []
    for m in modes:
        val = {n: float(theta[names.index(n)]) for n in m.names}
        err = {n: float(se[names.index(n)]) for n in m.names}
        seen = [c for c in m.channels
                if abs(val[f"a_{m.tag}_{c}"]) > SIGNIFICANCE * err[f"a_{m.tag}_{c}"]]
        f, zeta = val[f"f_{m.tag}"], val[f"zeta_{m.tag}"]
        out.append({"physics": m.family, "frequency_hz": f,
                    "frequency_se_hz": err[f"f_{m.tag}"], "damping_ratio": zeta,
                    "damping_ratio_se": err[f"zeta_{m.tag}"], "channels": seen,
                    "parameters": val, "uncertainty": err,
                    "statement": (f"A resonance at {f:.2f} Hz (damping ratio {100 * zeta:.2g} %), "
                                  f"seen by {', '.join(seen) if seen else 'no channel clearly'}, "
                                  "that the model class cannot have (an out-of-plane, torsional "
                                  "or local mode, or a subsystem outside the model): kept in every "
                                  "fit as model discrepancy, not named as a finding.")})
    return out


def class_statement(case, disc):
    """The statement of a model that lacks a class of motion (:func:`outside_class`), or []
    (disc: the described model discrepancy)."""
    if not case.outside_class:
        return []
    freqs = ", ".join(f"{d['frequency_hz']:.2f}" for d in disc if d.get("fitted", True))
    return [f"The model lacks as many resonances in its band as it has ({freqs} Hz): a class "
            "of motion outside the model (torsional or out-of-plane modes of the frame, one per "
            "storey), not a subsystem. No change of the model's parameters is named, because "
            "catalogue families fitted to it would take up that motion's coupling to the "
            "model's own modes. Measure it (two accelerometers per floor, or one in the other "
            "direction) and update a model that has it."]


def refute_in_discrepancy(discrepancy, results, log):
    """Refuse accepted appendages whose resonance lies in the window of a model-discrepancy
    mode (within HOT_WINDOW of its frequency). The discrepancy stage offered an appendage at
    every floor for that resonance and none explained it as well as a free modal term, so
    an appendage tuned there takes up what the modal term leaves (its real residue, a
    neighbouring mode of the same origin), not an appendage the data show."""
    for r in results:
        if not (r["accepted"] and r["physics"] == "secondary_oscillator"):
            continue
        f_s = next(v for n, v in r["parameters"].items() if n.startswith("f_s"))
        near = [m.f0 for m in discrepancy if abs(f_s / m.f0 - 1.0) <= HOT_WINDOW]
        if near:
            why = (f"its resonance ({f_s:.2f} Hz) lies in the window of the model discrepancy "
                   f"at {near[0]:.2f} Hz, which no appendage explained as well as a free "
                   "modal term: it takes up that mode's misfit")
            r["accepted"], r["significant"], r["why_not"] = False, False, why
            log(f"  secondary_oscillator {r['location']}: not accepted: {why}")
