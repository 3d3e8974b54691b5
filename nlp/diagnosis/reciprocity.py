"""Sensor gains from reciprocity: what two tests with different driving points measure
without any model.

Maxwell-Betti reciprocity makes a linear structure's receptance matrix symmetric, H_qp =
H_pq (Ewins, Modal Testing, 2000, ch. 2.7), and so every FRF form of it (mobility,
accelerance). A test with the force at p measures g_q H_qp on the sensor at q; a test with
the force at q measures g_p H_pq on the sensor at p (g: each sensor's gain, the force
gauge's cancelling, as it moves with the shaker). Their ratio is g_q / g_p at every
frequency, whatever the structure is. So the same sensors used in two such tests fix the
ratio of their gains with no model at all, and a sensor-gain candidate that contradicts
it is absorbing model error, not reporting a calibration.

The ratio is read where both FRFs stand far above their noise: on the fitted half-power
windows of both tests. Each window gives the median of ln|R|; the estimate is the mean of
the windows' medians and its standard error their spread over sqrt(windows), floored at
the scatter of the points themselves (bins in one window correlate, windows at different
resonances do not share their errors).
"""

import math

import numpy as np

from nlp.diagnosis.evidence import AGREE
from nlp.diagnosis.fitting import window_bands

__all__ = ["reciprocal_pairs", "gain_contradiction", "refute_gains", "MIN_SE"]

MIN_SE = 0.002   # the ratio is never known better than 0.2 % (a calibration's own accuracy)


def reciprocal_pairs(case, others, idx):
    """Every pair (this test, another) with driving points p != q and a sensor at the other's
    driving point in each: {"test", "channel_q", "channel_p", "ln_ratio", "se",
    "windows"}. ln_ratio estimates ln(g_q / g_p) (module docstring). idx: this test's fitted
    points; the other test's are its own fitted points."""
    out = []
    p = case.target.force_dof
    if p is None:
        return out
    for o in others:
        c2 = o["case"]
        q = c2.target.force_dof
        if q is None or q == p:
            continue
        a = _channel_at(case, q)
        b = _channel_at(c2, p)
        if a is None or b is None or case.channels[a].output != c2.channels[b].output:
            continue
        if not np.array_equal(case.f, c2.f):
            continue
        pts = np.union1d(idx, o["idx"])
        meds, spread = [], []
        for band in window_bands(pts):
            k = pts[band]
            lr = np.log(np.abs(case.H[a, k] / c2.H[b, k]))
            meds.append(float(np.median(lr)))
            spread.append(1.4826 * float(np.median(np.abs(lr - np.median(lr)))) / math.sqrt(k.size))
        if len(meds) < 2:
            continue
        se = max(float(np.std(meds, ddof=1)) / math.sqrt(len(meds)), float(np.mean(spread)),
                 MIN_SE)
        out.append({"test": o["label"], "channel_q": case.channels[a].name,
                    "channel_p": c2.channels[b].name, "ln_ratio": float(np.mean(meds)),
                    "se": se, "windows": len(meds)})
    return out


def _channel_at(case, dof):
    """Index of the channel of case that measures the DOF dof, or None."""
    return next((i for i, ch in enumerate(case.channels) if ch.dof == dof), None)


def gain_contradiction(pairs, gains, errors):
    """Why a set of channel gains contradicts reciprocity, or "" when it does not.

    gains, errors : channel name -> fitted gain error g (H -> (1 + g) H) and its standard
    error, for the gains in the model (absent channels: 0 +- 0). A pair contradicts the
    gains when ln((1 + g_q) / (1 + g_p)) differs from the measured ratio by more than AGREE
    combined standard errors."""
    for pr in pairs:
        gq, gp = gains.get(pr["channel_q"], 0.0), gains.get(pr["channel_p"], 0.0)
        if pr["channel_q"] not in gains and pr["channel_p"] not in gains:
            continue
        implied = math.log((1 + gq) / (1 + gp))
        se = math.hypot(pr["se"], errors.get(pr["channel_q"], 0.0) / (1 + gq),
                        errors.get(pr["channel_p"], 0.0) / (1 + gp))
        if abs(implied - pr["ln_ratio"]) > AGREE * se:
            return (f"reciprocity: this test's {pr['channel_q']} over {pr['test']}'s "
                    f"{pr['channel_p']} (H_qp / H_pq, equal in any linear structure) measures "
                    f"their gain ratio at {math.exp(pr['ln_ratio']):.3f} (+- "
                    f"{100 * pr['se']:.1f} %), while the gains in the model make it "
                    f"{math.exp(implied):.3f}: the gain absorbs model error")
    return ""


def refute_gains(sel, results, log):
    """Refuse accepted sensor gains that contradict the gain ratios reciprocity fixes between
    the tests (nlp.diagnosis.reciprocity), with the gains already found."""
    if not sel.reciprocity:
        return
    have = {r["location"]["channel"]: r for r in sel.found if r["physics"] == "sensor_gain"}
    for r in results:
        if not (r["accepted"] and r["physics"] == "sensor_gain"):
            continue
        gains = {c: next(iter(x["parameters"].values())) for c, x in have.items()}
        errors = {c: next(iter(x["uncertainty"].values())) for c, x in have.items()}
        ch = r["location"]["channel"]
        gains[ch] = next(iter(r["parameters"].values()))
        errors[ch] = next(iter(r["uncertainty"].values()))
        why = gain_contradiction(sel.reciprocity, gains, errors)
        if why:
            r["accepted"], r["significant"], r["why_not"] = False, False, why
            log(f"  sensor_gain {r['location']}: not accepted: {why}")
