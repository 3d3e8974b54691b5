"""Sensor time delays from the phase of the FRFs.

A delay tau on one channel multiplies its FRF by exp(-j omega tau): the
magnitude is unchanged, so a log-magnitude fit never sees it, but the phase
error of that channel grows linearly with frequency. The structural FRFs of a
shear frame (collocated, or base input to any floor) are minimum phase: once
their magnitudes are fitted their phases follow, so a phase error that is
linear in frequency on one channel is the signature of an all-pass element in
the measurement chain, not of the structure.

For each channel the phase residual d = arg(H_x / H_a) at the fitted and
held-out points is fitted by d = -omega tau (weights 1 / sigma_phase^2), on the
circle (a delay of tens of ms wraps the phase several times over the band):
a grid over tau maximises sum w cos(d + omega tau), Gauss-Newton steps refine
it. The evidence is the chi-square drop divided by the dispersion that remains
(quasi-likelihood, as :mod:`.evidence`), less the BIC penalty of one parameter.

When most channels show the same delay it belongs to the common reference
(the input channel), and it is reported once as such.

Tests of one structure fitted jointly (:mod:`nlp.case.joint`) share their sensors: a
sensor's channels in every test are fitted with one delay, as one acquisition chain has
one delay. The per-test delays are kept beside it; they count as the same delay when
they differ by less than MIN_PHASE at the top of the band, the phase error a magnitude
fit leaves anyway.
"""

import math

import numpy as np

from nlp.diagnosis.evidence import BIC_ACCEPT, SIGNIFICANCE, random_effects

__all__ = ["wrap", "fit_delay", "delay_check", "TAU_MAX", "MIN_PHASE", "EXPLAINED"]

TAU_MAX = 0.2          # [s] largest delay looked for
MIN_PHASE = 0.2        # [rad] phase a delay must reach at the top of the band, and by which
                       # it must stand out from the other channels' (model phase errors of a
                       # magnitude fit reached 0.11 rad on the development nulls)
EXPLAINED = 0.9        # fraction of the channel's phase chi-square a delay must explain
MAX_SIGMA = 0.5        # [rad] points with a noisier phase are not used (wrapping)
DELAY_Z = 2 * SIGNIFICANCE   # the delay must be this many (quasi) standard errors from 0


def wrap(x):
    """Angle(s) wrapped to (-pi, pi] [rad]."""
    return np.angle(np.exp(1j * np.asarray(x, float)))


def fit_delay(omega, d, sigma, tau_max=TAU_MAX):
    """Weighted least-squares delay of one channel's phase residual, on the circle.

    Parameters
    ----------
    omega : ndarray
        Circular frequencies [rad/s].
    d : ndarray
        Phase residual arg(H_measured / H_model) [rad].
    sigma : ndarray
        Standard deviation of the measured phase [rad].
    tau_max : float
        Largest |tau| searched [s].

    Returns
    -------
    dict
        tau [s], standard_error [s] (inflated by the dispersion phi), chi2_null
        (tau = 0), chi2 (at tau), phi, points, delta_bic (scaled; negative is
        evidence for the delay).
    """
    omega, d, w = map(np.asarray, (omega, d, 1.0 / np.asarray(sigma, float) ** 2))
    n = omega.size
    wmax = float(np.max(omega))
    grid = np.linspace(-tau_max, tau_max, int(np.ceil(8 * tau_max * wmax / np.pi)) + 1)
    score = (w[None, :] * np.cos(d[None, :] + grid[:, None] * omega[None, :])).sum(axis=1)
    tau = float(grid[int(np.argmax(score))])
    info = float(np.sum(w * omega ** 2))
    for _ in range(6):  # Gauss-Newton on the wrapped residual e = d + omega tau
        e = wrap(d + omega * tau)
        tau -= float(np.sum(w * omega * e)) / info
    chi0 = float(np.sum(w * wrap(d) ** 2))
    chi1 = float(np.sum(w * wrap(d + omega * tau) ** 2))
    phi = max(1.0, chi1 / max(n - 1, 1))
    return {"tau": tau, "standard_error": math.sqrt(phi / info), "chi2_null": chi0,
            "chi2": chi1, "phi": phi, "points": int(n), "omega_max": wmax,
            "explained": 1.0 - chi1 / chi0 if chi0 > 0 else 0.0,
            "delta_bic": (chi1 - chi0) / phi + math.log(max(n, 2))}


def _significant(r):
    """Strong evidence, a clearly non-zero delay that explains most of the phase misfit,
    and a phase error that matters at the top of the band."""
    return (r["delta_bic"] <= -BIC_ACCEPT and abs(r["tau"]) > DELAY_Z * r["standard_error"]
            and r["explained"] >= EXPLAINED and abs(r["tau"]) * r["omega_max"] >= MIN_PHASE)


def delay_check(f, H_meas, H_model, sigma_phase, names, sensors=None):
    """Delays of every sensor from the phase residual; findings for the significant ones.

    Parameters
    ----------
    f : ndarray, shape (n_f,)
        Frequencies [Hz] (fitted and held-out points of the diagnosis).
    H_meas, H_model : ndarray, shape (n_ch, n_f)
        Measured and model FRFs in the same form (complex).
    sigma_phase : ndarray, shape (n_ch, n_f)
        Standard deviation of the measured phase [rad].
    names : sequence of str
        Channel names.
    sensors : sequence of str, optional
        The physical sensor of each channel (default: each channel its own sensor). The
        channels of one sensor share one delay.

    Returns
    -------
    dict
        ``channels``: per sensor {channel (the sensor), delay_ms, standard_error_ms,
        delta_bic, phi, points, significant, and when the sensor has several channels
        per_channel: each channel's own delay_ms and standard_error_ms, and consistent};
        ``findings``: sensor_delay findings (one per sensor, or one on the input when
        most sensors share the delay).
    """
    omega = 2 * np.pi * np.asarray(f, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        D = np.angle(np.asarray(H_meas) / np.asarray(H_model))
    sensors = list(names) if sensors is None else list(sensors)
    rows = _sensor_rows(omega, D, sigma_phase, names, sensors)
    sig = [r for r in rows if r["significant"]]
    findings = []
    if rows and len(sig) > len(rows) / 2:
        # one delay shared by most channels: the common reference (input) is late, so
        # every output looks early by the same amount
        taus = np.array([r["delay_ms"] for r in sig])
        errs = np.array([r["standard_error_ms"] for r in sig])
        wts = 1 / errs ** 2
        mean = float(np.sum(wts * taus) / np.sum(wts))
        if np.all(np.abs(taus - mean) <= SIGNIFICANCE * np.sqrt(errs ** 2 + 1 / np.sum(wts))):
            se = float(1 / math.sqrt(np.sum(wts)))
            findings.append(_finding("input", -mean, se, sig, shared=True))
            return {"channels": rows, "findings": findings}
    for r in sig:
        # a channel's own delay stands out from the phase errors the other channels share
        others = [o["delay_ms"] for o in rows if o is not r]
        ref = float(np.median(others)) if others else 0.0
        if abs(r["delay_ms"] - ref) * 1e-3 * r["omega_max"] < MIN_PHASE:
            r["significant"] = False
            continue
        findings.append(_finding(r["channel"], r["delay_ms"], r["standard_error_ms"], [r]))
    return {"channels": rows, "findings": findings}


def _sensor_rows(omega, D, sigma_phase, names, sensors):
    """One delay row per sensor (its channels fitted together), or one per channel, marked
    test-specific, when a sensor's channels disagree."""
    usable = np.isfinite(D) & np.isfinite(sigma_phase) & (sigma_phase < MAX_SIGMA) & (omega > 0)
    rows = []
    for sensor in dict.fromkeys(sensors):
        parts = [(name, omega[ok], D[c, ok], sigma_phase[c, ok])
                 for c, (name, ok) in enumerate(zip(names, usable))
                 if sensors[c] == sensor and ok.sum() >= 10]
        if not parts:
            continue
        own = [_row(name, fit_delay(w, d, s)) for name, w, d, s in parts]
        if len(parts) == 1:
            rows += own
            continue
        row = _row(sensor, fit_delay(*(np.concatenate([p[k] for p in parts]) for k in (1, 2, 3))))
        row["per_channel"] = [{k: o[k] for k in ("channel", "delay_ms", "standard_error_ms")}
                              for o in own]
        # the channels' own delays differ by more than their noise when each test's phase
        # error pulls them its way: that spread bounds how well the one delay is known
        tau, se = random_effects([o["delay_ms"] for o in own],
                                 [o["standard_error_ms"] for o in own])
        row["between_tests_ms"] = tau
        row["standard_error_ms"] = max(row["standard_error_ms"], se)
        # a channel agrees when its own delay is within a magnitude fit's phase error of
        # the shared one, or too uncertain to tell them apart (a test that cannot see it)
        row["consistent"] = bool(all(
            abs(o["delay_ms"] - row["delay_ms"]) * 1e-3 * o["omega_max"] < MIN_PHASE
            or abs(o["delay_ms"] - row["delay_ms"]) < DELAY_Z * o["standard_error_ms"]
            for o in own))
        if row["consistent"] or not any(o["significant"] for o in own):
            rows.append(row)
        else:
            # the tests disagree: each channel's own delay, reported as test-specific
            for o in own:
                o["test_specific"] = row["per_channel"]
            rows += own
    return rows


def _row(channel, r):
    return {"channel": channel, "delay_ms": 1e3 * r["tau"],
            "standard_error_ms": 1e3 * r["standard_error"],
            "delta_bic": r["delta_bic"], "phi": r["phi"], "points": r["points"],
            "explained": r["explained"], "omega_max": r["omega_max"],
            "significant": _significant(r)}


def _finding(channel, tau_ms, se_ms, rows, shared=False):
    name = f"delay_ms_{channel}"
    where = ("the input (reference) channel: every output leads by the same time"
             if shared else f"channel {channel}")
    bic = float(sum(r["delta_bic"] for r in rows))
    evidence = {"source": "phase", "delta_bic": bic, "channels": [r["channel"] for r in rows]}
    tests, r = "", rows[0]
    each = ", ".join(f"{p['delay_ms']:.3g} ms on {p['channel']}"
                     for p in r.get("per_channel", r.get("test_specific", [])))
    if not shared and "per_channel" in r:
        evidence["per_channel"] = r["per_channel"]
        tests = f" One delay for the sensor in every test ({each} when fitted apart)."
    elif not shared and "test_specific" in r:
        evidence["test_specific"] = r["test_specific"]
        tests = (f" Test-specific: the sensor's channels in the tests fitted apart give {each},"
                 " which differ by more than a magnitude fit's phase error, so the timing "
                 "changed between tests.")
    return {"physics": "sensor_delay", "location": {"channel": channel},
            "parameters": {name: tau_ms}, "uncertainty": {name: se_ms},
            "evidence": evidence,
            "statement": (f"The phase of {where} {'lags' if tau_ms >= 0 else 'leads'} the "
                          f"model's by a time delay of {abs(tau_ms):.3g} +- {se_ms:.2g} ms "
                          "(a phase error growing linearly "
                          "with frequency, which no structural change produces; the "
                          "magnitudes are unaffected): check the acquisition timing, and "
                          "whether this channel's conditioning (its anti-alias filter's order "
                          "and corner) matches the reference's, since a filter's group delay "
                          "reads as a delay." + tests)}
