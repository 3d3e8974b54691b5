"""Screening of a case's data before any fitting: does the data contradict the set-up?

A wrong force floor, two swapped channels or a sensor mounted (or wired) with
the opposite sign make any model fit badly, and a physics search would then
blame missing physics. These checks use only properties that every linear,
passive chain-like structure has, so they hold whatever the parameter values:

* **Sign (first mode).** In the lowest mode every floor moves in phase (the
  lowest mode of a connected mass-spring chain has no node). At the first
  resonance the quadrature part Im(A_c) of every channel's accelerance has one
  sign: positive for a force input (A = -w^2 phi_c phi_p / (2j zeta w_1^2 m)),
  negative for ground input (relative response -Gamma phi_c / (...)). A channel
  with the other sign reads with the opposite sign (a phase offset of pi). The
  lowest resonance found counts as the first mode only when it lies nearer the
  nominal model's mode 1 than its mode 2; otherwise (the first mode outside the
  coherent band) this check and the channel-order check are skipped, with a warning.
* **Driving point (force input).** A collocated accelerance is positive-real
  times jw: Im(A_pp) >= 0 at every frequency, and poles and zeros alternate
  (one anti-resonance between consecutive resonances). A transfer FRF changes
  the sign of its quadrature at some mode, because sum_r phi_ir phi_pr / m_r =
  (M^-1)_ip = 0 for i != p. The channel whose quadrature is positive at every
  resonance is the driving point; if it is not at the floor the case names,
  the force floor (or the channel labels) is wrong.
* **Channel order.** The measured operating shapes at the resonances (the
  quadrature vectors) are compared by MAC with the nominal model's mode shapes;
  when exchanging two channels' data matches much better, and (shear frames) the
  lower floor of the pair moves more than the upper one in the first mode, which
  no shear chain can do, the channels are swapped. The nominal shapes alone are
  not enough: with stiffness changes of 30 % a false exchange can match better.
* **Coherence and H1 against H2.** |H1| / |H2| = gamma^2, so the gap between
  the two estimators is -10 log10(gamma^2) dB; dips at resonances point to
  input noise or force drop-out. With one segment, gamma^2 = 1 by construction
  and carries no information.

``screen(case)`` returns a dict (written to diagnosis.json as "screening"):
``setup_errors`` (each a dict with ``kind`` and ``message``), ``warnings``,
and the per-check numbers. Functions in ``RECORD_CHECKS`` (for example a
spike/dropout detector for time histories) are called with the case and
return extra warnings or set-up errors in the same form; the spikes and dropouts
that nlp/quality.py found when the records were read are reported as warnings.
"""

import os

import numpy as np
from scipy import signal

from nlp.case.assemble import assemble, single_tests
from nlp.case.selection import detection_form
from nlp.model.damping import band_modes
from nlp.output.progress import advance
from nlp.output.results import write_json

__all__ = ["screen", "screen_stage", "RECORD_CHECKS", "first_mode_signs", "driving_points", "swap_test"]

RECORD_CHECKS = []          # callables case -> list of {"kind", "message", "severity"}

PEAK_PROMINENCE_DB = 6.0    # a resonance stands 6 dB above its surroundings in the channel sum
PEAK_MIN_BINS = 3           # ... and is at least 3 bins wide at half its prominence
QUAD_DOMINANT = 0.5         # quadrature counts when |Im A| >= 0.5 |A| (the mode dominates)
QUAD_LEVEL = 0.05           # ... and |A_c| >= 5 % of the largest channel at that resonance
MAC_GAIN = 0.12             # a swap must raise the mean MAC by this much ...
MAC_GOOD = 0.9              # ... to at least this
COHERENCE_LOW = 0.5
H1H2_DB = 1.0               # gap at resonances worth a warning [dB]


# ------------------------------------------------------------------ pieces
def _band(case):
    """Indices of usable points: inside fmin..fmax, f > 0, coherent when known."""
    fc = case.config.frequencies
    f = case.f
    m = f > 0
    if fc.fmin is not None:
        m &= f >= fc.fmin
    if fc.fmax is not None:
        m &= f <= fc.fmax
    if case.coherence is not None and _segments(case) > 1:
        m &= np.min(case.coherence, axis=0) >= COHERENCE_LOW
    return np.nonzero(m)[0]


def _segments(case):
    """Welch segments averaged in the estimate (1: one segment or an FRF file)."""
    if getattr(case, "n_averages", None) is not None:
        return int(case.n_averages)
    d = case.config.data
    if case.records is None or d.nperseg == "all":
        return 1
    n = case.records.t.size
    nper = int(d.nperseg) if d.nperseg is not None else max(2 ** int(np.log2(max(n // 8, 1))), 1)
    step = max(nper - int(d.overlap * nper), 1)
    return max((n - nper) // step + 1, 1)


def resonances(f, D, idx, max_peaks):
    """Bins of the resonances: peaks of sum_c |D_c| / median|D_c| standing
    PEAK_PROMINENCE_DB above their surroundings and PEAK_MIN_BINS wide, the most
    prominent max_peaks,
    in increasing frequency."""
    A = np.abs(D[:, idx])
    s = np.sum(A / (np.median(A, axis=1, keepdims=True) + 1e-300), axis=0)
    db = 20 * np.log10(s + 1e-300)
    # a resonance spans several bins at half its prominence; a noise bump of a
    # one-segment estimate is one or two bins wide
    pk, prop = signal.find_peaks(db, prominence=PEAK_PROMINENCE_DB, width=PEAK_MIN_BINS,
                                 rel_height=0.5)
    keep = np.argsort(-prop["prominences"])[:max_peaks]
    return np.sort(idx[pk[keep]])


def _quadrature(D, peaks):
    """Q[c, p] = Im D_c at peak p, and whether it is dominant and large enough."""
    Dp = D[:, peaks]
    Q = Dp.imag
    mag = np.abs(Dp)
    sig = (np.abs(Q) >= QUAD_DOMINANT * mag) & (mag >= QUAD_LEVEL * mag.max(axis=0, keepdims=True))
    return Q, sig


def first_mode_signs(Q, sig, expected):
    """Channels whose first-mode quadrature has the sign opposite to `expected`
    (+1 force, -1 ground), and whether all significant channels are opposite."""
    s = np.sign(Q[:, 0]) * expected
    use = sig[:, 0]
    flipped = np.nonzero(use & (s < 0))[0]
    return flipped, bool(use.sum() >= 2 and flipped.size == use.sum())


def driving_points(Q, sig):
    """Channels whose quadrature is positive at every resonance where it counts
    (at least two): the collocated (driving-point) accelerances."""
    n_sig = sig.sum(axis=1)
    ok = np.all((Q > 0) | ~sig, axis=1) & (n_sig >= 2)
    return np.nonzero(ok)[0]


def _mac(a, b):
    den = (a @ a) * (b @ b)
    return float((a @ b) ** 2 / den) if den > 0 else 0.0


def _shape_score(Phi, Q):
    """Mean over model modes of the best MAC with any measured resonance."""
    return float(np.mean([max(_mac(Phi[:, r], Q[:, p]) for p in range(Q.shape[1]))
                          for r in range(Phi.shape[1])]))


def swap_test(Phi, Q, floors):
    """Identity score and the best pair exchange (score, (c1, c2)) of the measured
    quadrature shapes Q (n_ch, n_peaks) against model shapes Phi (n_ch, n_modes)."""
    base = _shape_score(Phi, Q)
    best = (base, None)
    for a in range(Q.shape[0]):
        for b in range(a + 1, Q.shape[0]):
            if floors[a] == floors[b]:
                continue
            Qs = Q.copy()
            Qs[[a, b]] = Qs[[b, a]]
            sc = _shape_score(Phi, Qs)
            if sc > best[0]:
                best = (sc, (a, b))
    return base, best


def _model_shapes(case, floors, n_modes):
    """Nominal-model mode shapes at the channels' floors (floor 0, the base: 0)."""
    _, V = band_modes(case.model.M0, case.model.K0, min(n_modes, case.model.n))
    return np.array([V[fl - 1] if fl > 0 else np.zeros(V.shape[1]) for fl in floors])


def _first_is_mode_one(case, f_first):
    """Is the lowest resonance found the structure's first mode? It is taken so when it
    lies nearer (in log frequency) the nominal model's mode 1 than its mode 2: the checks
    that rest on the first mode (every floor in phase) are meaningless at mode 2, where
    the upper floors move against the lower ones. When the coherence of some channels
    falls below the case's limit around mode 1, the coherent band begins above it, and
    the in-phase test would read mode 2 as sign-flipped channels (see
    docs/method/diagnosis.md)."""
    omega, _ = band_modes(case.model.M0, case.model.K0, min(2, case.model.n))  # FE models: sparse
    f_nom = np.sort(omega) / (2 * np.pi)
    if f_nom.size < 2 or f_nom[0] <= 0:
        return True, f_nom
    return bool(f_first < np.sqrt(f_nom[0] * f_nom[1])), f_nom


def _first_mode_disorder(case, Q, sig, floors, pair):
    """True when, as labelled, the lower floor of the pair moves more than the upper
    one in the first mode: impossible in a shear chain, whose lowest mode grows with
    height whatever its masses and stiffnesses (the nominal shapes compared by MAC
    are not: a 30 % stiffness change moves them enough to favour a false swap).
    Other models keep the MAC test alone."""
    if case.config.model.type != "shear_frame":
        return True
    a, b = sorted(pair, key=lambda c: floors[c])
    if not (sig[a, 0] and sig[b, 0]) or floors[a] == 0:
        return False
    return abs(Q[a, 0]) > abs(Q[b, 0])


def _antiresonances(f, D, peaks):
    """Per channel, the zeros (anti-resonances) between consecutive resonances.

    Between two poles an accelerance's real part keeps its sign unless a zero lies
    between them, where it changes sign (driving point: + after one resonance, -
    before the next). Counted outside the peaks' own half-power region (|D| above
    1/4 of the peak) and ignoring points more than 30 dB below the smaller peak, where
    noise flips the sign of a vanishing real part.
    """
    out = []
    for c in range(D.shape[0]):
        a = np.abs(D[c])
        k = 0
        for p, q in zip(peaks[:-1], peaks[1:]):
            seg = np.arange(p, q + 1)
            inside = (a[seg] < 0.25 * a[p]) & (a[seg] < 0.25 * a[q])
            if not inside.any():
                continue
            lo, hi = np.nonzero(inside)[0][[0, -1]]
            s = seg[lo:hi + 1]
            s = s[a[s] > 10 ** (-1.5) * min(a[p], a[q])]
            sg = np.sign(D[c, s].real)
            k += int(np.sum(sg[1:] != sg[:-1]))
        out.append(k)
    return out


# -------------------------------------------------------------------- main
def screen(case):
    """Check the case's data against its set-up before fitting (see the module doc).

    Parameters
    ----------
    case : nlp.case.assemble.Case
        The assembled case (measured FRFs, channels, excitation, nominal model).

    Returns
    -------
    dict
        ``setup_errors``: list of {"kind", "message", ...}; ``warnings``: list of
        the same; ``checks``: resonance frequencies [Hz], first-mode quadrature
        signs, driving-point channels, anti-resonance counts, shape MAC scores,
        coherence and H1/H2 gaps.
    """
    names = [ch.name for ch in case.channels]
    floors = [ch.dof + 1 for ch in case.channels]
    D = detection_form(case.f, case.H, case.channels, case.target.excitation)
    idx = _band(case)
    errors, warnings, checks = [], [], {}
    peaks = resonances(case.f, D, idx, case.model.n + 2) if idx.size > 4 else np.array([], int)
    checks["resonances_hz"] = [float(x) for x in case.f[peaks]]
    if peaks.size >= 1:
        Q, sig, mode_one = _sign_checks(case, D, peaks, names, floors, errors, warnings, checks)
        swap = _swap_check(case, Q, sig, peaks, names, floors, mode_one, errors, checks)
        _force_floor_check(case, D, Q, sig, peaks, names, floors, swap, errors, checks)
    else:
        warnings.append({"kind": "no_resonance", "message": "no resonance stands out in the band: "
                                                             "the set-up checks were skipped"})
    _coherence(case, peaks, names, warnings, checks)
    _record_quality(case, warnings, checks)
    for check in RECORD_CHECKS:
        for item in check(case):
            (errors if item.get("severity") == "error" else warnings).append(item)
    return {"setup_errors": errors, "warnings": warnings, "checks": checks}


def screen_tests(case):
    """:func:`screen` of a case; tests fitted jointly (data.tests) are screened one by one,
    as each has its own driving point, and their messages name the test."""
    cfg = case.config
    if not cfg.data.tests:
        return screen(case)
    out = {"setup_errors": [], "warnings": [], "checks": {}}
    for label, c_cfg, path in single_tests(cfg):
        rep = screen(assemble(c_cfg, data_file=path))
        for kind in ("setup_errors", "warnings"):
            out[kind] += [dict(x, test=label, message=f"{label}: {x['message']}")
                          for x in rep[kind]]
        out["checks"][label] = rep["checks"]
    return out


def _sign_checks(case, D, peaks, names, floors, errors, warnings, checks):
    """Phase convention and sign-flipped channels at the first resonance, where every
    floor moves in phase. Returns the quadrature Q (flips undone), its significance sig,
    and whether the first resonance is mode 1."""
    Q, sig = _quadrature(D, peaks)
    expected = 1.0 if case.target.excitation == "force" else -1.0
    mode_one, f_nom = _first_is_mode_one(case, case.f[peaks[0]])
    flipped, all_flipped = first_mode_signs(Q, sig, expected) if mode_one else \
        (np.array([], int), False)
    checks["first_mode_quadrature_sign"] = dict(zip(names, np.sign(Q[:, 0]).tolist()))
    if not mode_one:
        warnings.append({"kind": "first_mode_unseen",
                         "message": f"the lowest resonance in the coherent band "
                                    f"({case.f[peaks[0]]:.3g} Hz) lies nearer the nominal "
                                    f"model's mode 2 ({f_nom[1]:.3g} Hz) than its mode 1 "
                                    f"({f_nom[0]:.3g} Hz): the sign and channel-order checks, "
                                    "which need the first mode, were skipped"})
    if all_flipped:
        w = {"kind": "phase_convention",
             "message": "every channel has the opposite phase at the first resonance: the "
                        "input's sign or the FRF phase convention is reversed"}
        (errors if case.config.objective.residual == "complex" else warnings).append(w)
        Q = -Q
    elif flipped.size and 2 * flipped.size < sig[:, 0].sum():
        for c in flipped:
            errors.append({"kind": "sign_flip", "channel": names[c],
                           "message": f"channel {names[c]} (floor {floors[c]}) reads with the "
                                      f"opposite sign: at the first resonance "
                                      f"({case.f[peaks[0]]:.3g} Hz), where every floor moves in "
                                      "phase, its phase is offset by pi from the other channels'. "
                                      "Check the sensor's orientation and wiring (or give the "
                                      "channel sign: -1)."})
        Q[flipped] = -Q[flipped]
    return Q, sig, mode_one


def _swap_check(case, Q, sig, peaks, names, floors, mode_one, errors, checks):
    """Two channels whose exchange makes the measured shapes match the model's; returns
    the swapped pair of channel indices, or None."""
    if not (peaks.size >= 2 and len(set(floors)) >= 3):
        return None
    Phi = _model_shapes(case, floors, min(case.model.n, peaks.size))
    base, (best, pair) = swap_test(Phi, Q, floors)
    checks["shape_mac"] = {"as_labelled": base, "best_exchange": best,
                           "exchange": [names[c] for c in pair] if pair else None}
    if not (pair and mode_one and best >= base + MAC_GAIN and best >= MAC_GOOD
            and _first_mode_disorder(case, Q, sig, floors, pair)):
        return None
    a, b = pair
    errors.append({"kind": "swapped_channels", "channels": [names[a], names[b]],
                   "message": f"channels {names[a]} (floor {floors[a]}) and {names[b]} "
                              f"(floor {floors[b]}) appear swapped: the measured shapes "
                              f"at the resonances match the model's mode shapes with MAC "
                              f"{best:.2f} when their data are exchanged, {base:.2f} as "
                              "labelled. Check the channel order."})
    return pair


def _force_floor_check(case, D, Q, sig, peaks, names, floors, swap, errors, checks):
    """The force's floor: the driving point is the channel whose quadrature is positive
    at every resonance (with an anti-resonance between each pair)."""
    # the force-floor test uses the resonances most channels see clearly (a noise
    # bump of a one-segment estimate has a random phase on each channel)
    clear = sig.sum(axis=0) >= max(2, (sig.shape[0] + 1) // 2)
    if not (case.target.excitation == "force" and clear.sum() >= 2):
        return
    dp = driving_points(Q[:, clear], sig[:, clear])
    checks["driving_point_channels"] = [names[c] for c in dp]
    checks["antiresonances_between_peaks"] = dict(zip(names, _antiresonances(case.f, D, peaks)))
    p = case.target.force_dof + 1
    at_p = [c for c, fl in enumerate(floors) if fl == p]
    others = sorted({floors[c] for c in dp if floors[c] != p})
    if not (at_p and not any(c in dp for c in at_p) and len(others) == 1 and (
            swap is None or p not in (floors[swap[0]], floors[swap[1]]))):
        return
    c = at_p[0]
    bad = [f"{case.f[peaks[k]]:.3g}" for k in range(peaks.size)
           if clear[k] and sig[c, k] and Q[c, k] < 0]
    good = [names[k] for k in dp]
    zeros = checks["antiresonances_between_peaks"]
    errors.append({"kind": "force_floor", "stated_floor": p, "data_floor": others[0],
                   "message": f"the case puts the force at floor {p}, but channel "
                              f"{names[c]} (floor {p}) is not a driving point: its "
                              f"quadrature changes sign (negative at {', '.join(bad)} Hz), "
                              f"while {', '.join(good)} (floor {others[0]}) is positive at "
                              f"every resonance, as only the driving point can be "
                              f"({zeros[good[0]]} anti-resonances between its {peaks.size} "
                              f"resonances against {zeros[names[c]]} for {names[c]}; a "
                              "driving point has one between each pair). The "
                              f"force appears to act at floor {others[0]}: check "
                              "excitation.floor (or the channel labels)."})


def _coherence(case, peaks, names, warnings, checks):
    """Coherence dips and the H1/H2 gap (-10 log10 gamma^2 dB) at the resonances."""
    if case.coherence is None:
        return
    if _segments(case) == 1:
        checks["coherence"] = "one segment: coherence is 1 and H1 = H2 by construction"
        return
    fc = case.config.frequencies
    m = case.f > 0
    if fc.fmin is not None:
        m &= case.f >= fc.fmin
    if fc.fmax is not None:
        m &= case.f <= fc.fmax
    g2 = np.clip(case.coherence, 1e-12, 1)
    low = {n: float(np.mean(g2[c, m] < COHERENCE_LOW)) for c, n in enumerate(names)}
    checks["low_coherence_fraction"] = low
    for n, frac in low.items():
        if frac > 0.2:
            warnings.append({"kind": "coherence", "channel": n,
                             "message": f"channel {n}: coherence below {COHERENCE_LOW} on "
                                        f"{100 * frac:.0f} % of the band"})
    if peaks.size:
        gap = -10 * np.log10(g2[:, peaks])
        checks["h1_h2_gap_db_at_resonances"] = dict(zip(names, gap.max(axis=1).tolist()))
        if np.median(gap) > H1H2_DB:
            warnings.append({"kind": "h1_h2", "message": f"H1 and H2 differ by {np.median(gap):.1f} "
                             "dB (median) at the resonances: input noise or force drop-out; H1 "
                             "underestimates the peaks"})



def _record_quality(case, warnings, checks):
    """Spikes and dropouts found in the records when they were read (nlp/quality.py)."""
    rep = getattr(case, "quality", None)
    if rep is None:
        return
    counts = rep.counts()
    checks["record_quality"] = counts
    for ch, c in counts.items():
        if c["spikes"] or c["dropouts"]:
            warnings.append({"kind": "record_quality", "channel": ch,
                             "message": f"records, channel {ch}: {c['spikes']} spike(s) and "
                                        f"{c['dropouts']} dropout(s), {100 * c['fraction_flagged']:.2g} % "
                                        "of the samples" + (" (repaired before estimating the FRFs)"
                                                            if rep.removed else
                                                            "; data.screen.remove: true repairs them")})

def setup_error_result(report):
    """The diagnosis of a case whose data contradict its set-up: no physics is
    blamed, the set-up errors are stated, and the screening is attached."""
    msgs = [e["message"] for e in report["setup_errors"]]
    return {"verdict": "setup_error", "findings": [], "alternatives": [], "absorbed": [],
            "summary": ["The data contradict the case's set-up; no physics was fitted or blamed. "
                        "Correct the case (or the data) and run again."] + msgs,
            "remaining_mismatch": False, "fit": {}, "residual_map": {},
            "suggested_measurements": [], "screening": report}


def screen_stage(cfg, case, out, log):
    """Screen the data before fitting (nlp.diagnosis.screen). A case that contradicts its
    data gets the verdict setup_error, written to out/diagnosis.json; otherwise
    {"verdict": None, "report": the screening} for the diagnosis to carry."""
    advance("diagnose", "screen")
    report = screen_tests(case)
    for w in report["warnings"]:
        log(f"screening: {w['message']}")
    if not report["setup_errors"]:
        return {"verdict": None, "report": report}
    result = dict(case=cfg.name, case_file=cfg.path, **setup_error_result(report))
    os.makedirs(out, exist_ok=True)
    write_json(os.path.join(out, "diagnosis.json"), result)
    log("verdict: setup_error (the data contradict the case; no physics is blamed)")
    for e in report["setup_errors"]:
        log(f"  set-up error: {e['message']}")
    return result
