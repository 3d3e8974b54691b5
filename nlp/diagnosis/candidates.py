"""Candidate physics: every family x location, ranked by a score test at its null value.

The score of a candidate is the expected chi-square drop of freeing its parameters: the
baseline residual projected off the baseline Jacobian, onto the candidate's Jacobian
columns. Candidates whose columns lie almost inside the baseline span are absorbed by the
baseline parameters (ABSORBED) and reported as such, not guessed at.
"""

import numpy as np

from nlp.diagnosis.families import (AddedMass, BaseFlexibility, FrameAction, HystereticDamping,
                                    LocalDamper,
                                    NonadjacentCoupling, SecondaryOscillator, SensorDelay,
                                    SensorGain)
from nlp.diagnosis.locations import case_floors, floor_count, is_fe, mass_floors, story_count
from nlp.diagnosis.fitting import (diagnosis_problem, case_references, projected_columns,
                                   window_bands, with_values)
from nlp.frf.backends.terms import proportional

ABSORBED = 0.05        # fraction of a candidate's effect left after projection
# an appendage's score is taken with a tiny oscillator: mass ratio, damping ratio
PROBE_MU, PROBE_ZETA = 1e-4, 0.02
NEAR_RESONANCE = 0.1   # relative distance from a fitted resonance where any oscillator scores


def candidates(case):
    """Every family x location that the data could reveal, but the secondary
    oscillator (scanned separately; sensor delay needs the phase). Locations are the
    model's floors (an FE model's mass-carrying node levels, nlp.diagnosis.locations) and
    stories (an FE model's stiffness groups); frame action is a shear-frame family."""
    n = floor_count(case)
    fe = is_fe(case.model)
    out = [AddedMass(i) for i in (mass_floors(case.model, case_floors(case)) if fe
                                  else range(1, n + 1))]
    if base_candidate(case):
        out.append(BaseFlexibility())
    out += [LocalDamper(i, i - 1) for i in range(1, n + 1)]
    out += [HystereticDamping()] + [HystereticDamping(s)
                                    for s in range(1, story_count(case.model) + 1)]
    out += [NonadjacentCoupling(i, j) for i in range(1, n + 1) for j in range(i + 2, n + 1)]
    if n >= 2 and not fe:
        out.append(FrameAction())
    # one per sensor: tests fitted jointly share their sensors (nlp.case.joint)
    sensors = list(dict.fromkeys(ch.sensor_name for ch in case.channels))
    if not case.config.data.calibration:   # else gains beyond the tolerance: .calibration
        out += [SensorGain(s) for s in sensors]
    if case.config.objective.residual == "complex":
        out += [SensorDelay(s) for s in sensors]
    return out


def base_candidate(case):
    """Whether a flexible base is a candidate: on a shear frame always; on an FE model (its
    supports on one base DOF, :func:`nlp.frf.backends.terms._base`) when its damping is
    proportional, the form the sparse terms carry."""
    return not is_fe(case.model) or proportional(case.damping)


def same(e, current):
    """Whether the model `current` holds e's family at e's location already."""
    return any(c.family == e.family and c.location == e.location for c in current)


EVERY_LOCATION = ("sensor_gain",)   # families refitted at each location with a positive score


def to_refit(scored, top):
    """Every competitive candidate (score within a factor 3 of the best, at most
    2 x top) and the two best locations of every family: the score test is a
    first-order look, and a large effect can rank its true location second. A sensor
    gain is refitted on every channel that scores: one parameter per channel, and under a
    large structural misfit its first-order score is the least reliable
    (docs/method/diagnosis.md, section 4)."""
    if not scored:
        return []
    best = scored[0][0]
    chosen = [(s, e) for s, e in scored if s >= best / 3][:2 * top]
    count = {}
    for s, e in chosen:
        count[e.family] = count.get(e.family, 0) + 1
    for s, e in scored:
        wanted = count.get(e.family, 0) < 2 or e.family in EVERY_LOCATION
        if s > 0 and wanted and (s, e) not in chosen:
            chosen.append((s, e))
            count[e.family] = count.get(e.family, 0) + 1
    return chosen


def score_at(pr, z, k):
    """Expected chi-square drop of freeing the last k variables, and the fraction of
    their effect left after projecting out the baseline Jacobian."""
    r, J = pr.residuals(z)
    Q, Je, Jp = projected_columns(pr, J, k)
    rp = r - Q @ (Q.T @ r)
    raw = np.linalg.norm(Je)
    kept = float(np.linalg.norm(Jp) / raw) if raw > 0 else 0.0
    if kept < 1e-9:
        return 0.0, kept
    g = Jp.T @ rp
    return float(g @ np.linalg.pinv(Jp.T @ Jp) @ g), kept


def score(case, target, current, z_cur, enrichment):
    """Score test of one candidate at its null value, on top of the current model."""
    null = enrichment.spec(case_references(case))["null"]
    pr = diagnosis_problem(case, target, current + [enrichment], compile=False)
    return score_at(pr, with_values(pr, z_cur, null), len(enrichment.names))


def _has_appendage(current, floor):
    return any(e.family == "secondary_oscillator" and e.floor == floor for e in current)


def scan_secondary(case, target, current, z_cur, n_grid=48, resonances=()):
    """Appendage candidates per floor from the score of a tiny oscillator scanned over
    the fitted band (its frequency is a nuisance parameter, undefined under the null).

    Next to a resonance the score of any tiny oscillator is large (it splits the peak, on
    every floor alike), so when a floor's best frequency lies within NEAR_RESONANCE of a
    fitted resonance, the best frequency away from all of them is a second candidate of
    that floor, refitted from there: a refit started next to a resonance stays there,
    while one started at the true frequency finds it (see docs/method/diagnosis.md). Each
    candidate's refit also starts at the resonances the current model lacks
    (``resonances``, Hz; SecondaryOscillator.starts).
    """
    f_sel = case.f[case.selected]
    grid = np.geomspace(0.8 * f_sel.min(), 1.1 * f_sel.max(), n_grid)
    peaks = [float(np.mean(f_sel[g])) for g in window_bands(case.selected)]
    near = np.array([any(abs(f0 / fp - 1.0) <= NEAR_RESONANCE for fp in peaks) for f0 in grid])
    out = []
    for floor in range(1, floor_count(case) + 1):
        if _has_appendage(current, floor):
            continue
        e = SecondaryOscillator(floor, float(grid[0]))
        pr = diagnosis_problem(case, target, current + [e], compile=False)
        scores = [score_at(pr, with_values(pr, z_cur, [PROBE_MU, f0, PROBE_ZETA]), 3)
                  for f0 in grid]
        values = np.array([sc for sc, _ in scores])
        best = int(np.argmax(values))
        out.append((SecondaryOscillator(floor, float(grid[best]), resonances), scores[best]))
        if near[best] and not near.all():
            off = int(np.argmax(np.where(near, -np.inf, values)))
            out.append((SecondaryOscillator(floor, float(grid[off]), resonances), scores[off]))
    return out


def hot_appendages(case, target, current, z_cur, hot, resonances=()):
    """Appendage candidates tuned to the largest misfits off the fitted points (Hz, from
    band.hot_spots), one per floor that has none yet; they are refitted whatever their
    score. The score test is a first-order look, and the scan's best frequency can land
    next to a resonance, far from the appendage's own (see docs/method/diagnosis.md)."""
    out = []
    for h in hot:
        for floor in range(1, floor_count(case) + 1):
            if _has_appendage(current, floor):
                continue
            e = SecondaryOscillator(floor, float(h), resonances)
            pr = diagnosis_problem(case, target, current + [e], compile=False)
            out.append((e, score_at(pr, with_values(pr, z_cur, [PROBE_MU, h, PROBE_ZETA]), 3)))
    return out
