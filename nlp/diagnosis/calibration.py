"""Every channel's calibration, within the tolerance the case states, as a nuisance of every fit.

A transducer's sensitivity is known to its calibration certificate's tolerance (typically
1-5 % for accelerometers and displacement transducers). An FRF is the ratio of two
channels, so each H_c carries a gain (1 + e_c) / (1 + e_in) that no structural change
produces: flat over frequency, one per channel. Judged against a model without them, such
gains are real misfits of a few per cent on every channel; the data then prefer a named gain
error (or a structural change that absorbs one) to the structural effect actually present,
and a round of the selection is spent on what the lab's own certificate allows.

With ``data.calibration: t`` in the case, every fit of a diagnosis carries every channel's
gain inside the tolerance (:class:`Calibration`), so the baseline and every candidate are
judged with calibration present, as with the model discrepancy (:mod:`.discrepancy`). A
box, not a Gaussian prior: a certificate states bounds, and a box keeps the NLP a bounded
least-squares problem. A gain is a finding only beyond the tolerance: the driver frees the
gain of each sensor that sits on its bound, and names it when the freed fit passes the
evidence rules of one added parameter (scaled BIC, the held-out test) and the gain stands
SIGNIFICANCE standard errors beyond the tolerance, the test every finding's effect parameter
meets against its null (:func:`release_check`).
"""

from dataclasses import dataclass

import numpy as np

from nlp.diagnosis.evidence import (BIC_ACCEPT, SIGNIFICANCE, dispersion, held_out_ok,
                                    scaled_delta_bic)

__all__ = ["Calibration", "calibration_of", "gains_at_bound", "release_check", "RELEASED"]

RELEASED = (-0.5, 1.0)   # a freed gain's box: the sensor_gain family's own


@dataclass(frozen=True)
class Calibration:
    """Channel gains within the calibration tolerance: H_c -> (1 + g_c) H_c.

    g_c is channel c's gain relative to the input's, (1 + e_c) / (1 + e_in) with |e| <= t
    on each transducer, so g_c lies in [(1 - t) / (1 + t) - 1, (1 + t) / (1 - t) - 1].
    On a force test without a total-mass anchor a gain common to every channel is a
    scale of M, C and K, which the structure's free masses and stiffnesses carry: the
    reference sensor's gain is then held at 0 (not a parameter), the others relative to it.

    channels : sensor names with a gain (tests fitted jointly share it, nlp.case.joint).
    tolerance : relative tolerance t of every transducer's sensitivity [-].
    released : sensors whose gain is free beyond the tolerance (named gain errors).
    """

    channels: tuple
    tolerance: float
    released: tuple = ()
    family = "calibration"

    @property
    def names(self):
        return tuple(f"cal_{c}" for c in self.channels)

    @property
    def location(self):
        return {}

    @property
    def bounds(self):
        """(lower, upper) of a gain within the tolerance (a ratio of two transducers')."""
        t = self.tolerance
        return (1 - t) / (1 + t) - 1, (1 + t) / (1 - t) - 1

    def spec(self, ref):
        lo, hi = self.bounds
        free = [c in self.released for c in self.channels]
        n = len(self.channels)
        return {"initial": [0.0] * n, "lower": [RELEASED[0] if r else lo for r in free],
                "upper": [RELEASED[1] if r else hi for r in free], "scale": [0.01] * n,
                "null": [0.0] * n}

    def output_on(self, channel, hr, hi, w, th):
        """Channel's FRF (real, imaginary parts) through its calibration."""
        g = 1 + th[self.channels.index(channel)]
        return g * hr, g * hi


def calibration_of(case):
    """The case's Calibration (None when the case states no tolerance); the sensors whose
    gains a diagnosis has named as errors (case.released_gains, their findings) are free."""
    t = case.config.data.calibration
    if not t:
        return None
    sensors = tuple(dict.fromkeys(ch.sensor_name for ch in case.channels))
    if case.target.excitation != "ground" and case.config.parameters.total_mass is None:
        sensors = sensors[1:]    # the reference: the structure's scale carries a common gain
    return Calibration(sensors, float(t), released=tuple(
        f["location"]["channel"] for f in case.released_gains))


def gains_at_bound(cal, names, theta, rel=1e-3):
    """Sensors whose fitted gain sits on the tolerance (within rel of it): {sensor: g}."""
    out = {}
    for s in cal.channels:
        if s in cal.released:
            continue
        g = float(theta[names.index(f"cal_{s}")])
        if min(abs(g - b) for b in cal.bounds) <= rel * cal.tolerance:
            out[s] = g
    return out


def release_check(cal, sensor, fit0, fit1, n_fit, nu, held0, held1):
    """Whether freeing sensor's gain names a gain error: a dict of the evidence.

    fit0, fit1 : (chi2, theta, se, names) of the fits with the gain bounded and freed;
    n_fit, nu : fitted points and degrees of freedom of the bounded fit;
    held0, held1 : their held-out mean squared normalised residuals.
    """
    chi0, _, _, _ = fit0
    chi1, th1, se1, names = fit1
    i = names.index(f"cal_{sensor}")
    g, se = float(th1[i]), float(se1[i])
    phi = dispersion(chi1, max(nu - 1, 1))
    dbic = scaled_delta_bic(chi1, chi0, 1, n_fit, phi)
    lo, hi = cal.bounds
    beyond = max(lo - g, g - hi) / max(se, 1e-12)
    ok = bool(dbic < -BIC_ACCEPT and held_out_ok(held1, held0, "sensor_gain", dbic)
              and np.isfinite(se) and beyond >= SIGNIFICANCE)
    return {"sensor": sensor, "gain": g, "se": se, "delta_bic": float(dbic), "phi": phi,
            "beyond_se": float(beyond), "held_out": (held0, held1), "accepted": bool(ok)}
