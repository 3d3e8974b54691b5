"""Is a level dependence large enough to be a finding? The joints every real frame has.

Bolted and welded joints make every story of a real frame slightly level-dependent: its
equivalent stiffness changes by about 1 % between a test level and three times it (the size
issue 48 names as present in every real lab; steel test frames show amplitude-dependent
frequencies of this order). The level comparison (:func:`nlp.diagnosis.levels.shared_stiffness`)
is right that such a structure is not linear, and on good data it always will be. What an
engineer needs to hear is whether one linear model serves both levels: whether the equivalent
linear models of the levels can be brought within JOINT_CHANGE of each other in every story
stiffness and every floor mass (Eqns 23-24, each on its own, either sign; damping free, as in
the level comparison) and still fit both levels' data within BIC's price. Only when they
cannot is the level dependence a finding (:func:`banded_change`).

The masses are in the band as well although joints carry no mass: a level's equivalent
linear fit of resonances that a nonlinear story bends moves its masses as well as its
stiffnesses (on a development null with 0.5-0.8 % joints the high level's fitted floor
masses moved 2.3 % from the low level's, its stiffnesses 1.8 % at most).

JOINT_CHANGE = 3 %: the 1 % joints, as seen where an FRF is decided. An equivalent stiffness
3 k3 E[d^2] moves with the drift variance, and near a resonance the FRF is decided by the
Welch segments with the most drift: on 66 story draws (chirps and random drives) the
segment with the most drift carries 1.3-2.7 times the record's drift variance
(``research/joint_sizing.py``; docs/method/diagnosis.md), so 1 % joints look like up to
2.7 %, rounded up to 3 %. The family's smallest planted nonlinearity (0.06) changes its story
by 7-8 % between the levels on the blind benchmark; on the lab generator the band keeps
cubic springs of that size and gives up contacts, weak friction and sliding masses whose
equivalent masses and stiffnesses stay within it (docs/method/diagnosis.md, "The joints'
band, measured").
"""

from dataclasses import replace

import numpy as np

from nlp.diagnosis.fitting import best_fit, continued, diagnosis_problem
from nlp.diagnosis.level_kind import applies, level_kind, level_order

JOINT_CHANGE = 0.03   # largest story stiffness or floor mass change between levels from joints


def joint_gate(ref, lv, limit, own, phi, log):
    """(:func:`banded_change`'s result, the level kind or None): whether the level
    dependence is a finding (result["finding"]). Within the band it still is when the
    damping falls as the level rises (decided by :func:`nlp.diagnosis.level_kind.level_kind`):
    dry friction's equivalent damping goes as 1 / amplitude, which stiffening or softening
    joints do not do, while the damping of real frames rises with the amplitude.

    Harmonics that locate one story are not such a sign: joints differ from story to story,
    and on three of eleven development nulls within the band they located one story
    (docs/method/diagnosis.md, "The joints' band, measured")."""
    joints = banded_change(ref, lv, limit, own, phi)
    log(f"  masses and stiffnesses free within +-{100 * joints['delta']:.0f} % between the "
        f"levels (a real frame's joints): +{joints['excess']:.1f} (scaled; BIC limit "
        f"{joints['limit']:.1f})" + ("" if joints["material"] else ": within" if joints["within"]
                                     else ": not decided (unconverged)"))
    kind = None
    if not joints["material"] and applies(ref):
        kind = level_kind(ref, lv, phi["ref"], phi["lv"], level_order(ref, lv))
    joints["falling_damping"] = bool(kind and kind["kind"] == "damping" and kind["rises"] is False)
    joints["finding"] = joints["material"] or joints["falling_damping"]
    if not joints["material"]:
        log("  " + ("but the damping falls as the level rises (dry friction), which joints do "
                    "not do" if joints["falling_damping"] else "not a finding"))
    return joints, kind


def banded_change(ref, lv, limit, own, phi, delta=JOINT_CHANGE):
    """Can changes of at most ``delta`` in each mass and stiffness carry the levels' difference?

    Each level's data are refitted with every free story stiffness and floor mass within
    +-delta (relative) of the other level's optimum, damping free;
    the rise over the level's own fit is scaled by that fit's remaining misfit (as in
    :func:`nlp.diagnosis.levels.shared_stiffness`). Either way round is an upper bound of
    the likelihood ratio of the banded model, so the least is compared with ``limit``.
    own, phi: {"ref": .., "lv": ..}, each level's own chi-square and remaining misfit.

    Returns {"delta", "rises": {"other level": .., "reference": ..}, "excess", "limit",
    "converged", "material", "within"}. Every rise, converged or not, bounds the banded
    likelihood ratio from above, so a least rise under the limit shows the change is within
    the band; above it, the change is material only when that refit converged (as the level
    comparison asks of its shared fit) or stopped where a Gauss-Newton step's predicted
    decrease is smaller than the rise's excess over the limit; otherwise neither is shown.
    """
    rises, settled = {}, {}
    for key, (source, data, L) in {"other level": (ref, lv, "lv"),
                                   "reference": (lv, ref, "ref")}.items():
        res, pr = _banded_fit(source, data, delta)
        res = continued(pr, res)
        rise = max(float(2 * res.f) - own[L], 0.0) / phi[L]
        rises[key] = (rise, bool(res.success))
        # a refit stopped unconverged far above the limit still decides when the next
        # Gauss-Newton step's predicted decrease cannot close the gap (on a strongly
        # nonlinear level, reduced chi-square in the thousands, IPOPT ran out of
        # iterations at bounds; docs/method/diagnosis.md)
        settled[key] = bool(res.success) or (
            rise > limit and pr.gn_decrement(res.z) / phi[L] < rise - limit)
    at = min(rises, key=lambda k: rises[k][0])
    excess, ok = rises[at]
    return {"delta": float(delta), "rises": {k: v for k, (v, _) in rises.items()},
            "excess": excess, "limit": float(limit), "converged": ok, "way": at,
            "material": bool(excess > limit and settled[at]), "within": bool(excess <= limit)}


def band(theta_source, p, delta):
    """Bounds of a relative change theta (Eqns 23-24) that keep the stiffness or mass
    (1 + theta) x nominal within +-delta of (1 + theta_source) x nominal, inside the
    parameter's own bounds."""
    k = 1.0 + float(theta_source)
    lo, hi = max(k * (1.0 - delta) - 1.0, p.lower), min(k * (1.0 + delta) - 1.0, p.upper)
    return (lo, hi) if lo <= hi else (p.lower, p.upper)


def _banded_fit(source, data, delta):
    """``data``'s level fitted with its masses and stiffnesses within +-delta of
    ``source``'s optimum (damping free): (result, problem)."""
    pr_d, pr_s = data["problem"], source["problem"]
    sa, sb, _ = pr_d.params.slices()
    th_s = pr_s.theta(source["z"])
    th_d = pr_d.theta(data["z"])
    out = []
    for i, p in enumerate(pr_d.params.params):
        if p.fixed or not sa.start <= i < sb.stop:
            out.append(p)
        else:
            lo, hi = band(th_s[i], p, delta)
            out.append(replace(p, lower=lo, upper=hi,
                               initial=float(np.clip(th_d[i], lo, hi))))
    params = replace(pr_d.params, params=tuple(out))
    c = data["case"]
    pr = diagnosis_problem(c, pr_d.target, optimize=False, damping=(c.damping, params))
    # starts: the data's own optimum brought into the band, and the source's optimum
    start_own = np.array(th_d, float)
    start_src = np.array(th_d, float)
    for i in range(sa.start, sb.stop):
        p = params.params[i]
        start_own[i] = np.clip(th_d[i], p.lower, p.upper) if not p.fixed else p.initial
        start_src[i] = np.clip(th_s[i], p.lower, p.upper) if not p.fixed else p.initial
    return best_fit(pr, [params.z_from_theta(start_own), params.z_from_theta(start_src)]), pr
