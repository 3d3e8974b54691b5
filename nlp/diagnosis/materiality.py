"""Is a level dependence large enough to be a finding? The joints every real frame has.

Bolted and welded joints make every story of a real frame slightly level-dependent: its
equivalent stiffness changes by about 1 % between a test level and three times it (the
size issue 48 names as present in every real lab; steel test frames show amplitude-dependent
frequencies of this order). The level comparison (:func:`nlp.diagnosis.levels.shared_stiffness`)
is right that such a structure is not linear, and on good data it always will be; an
engineer wants to hear about a level dependence that a linear model per level cannot carry
within what the joints do. So a level dependence is a finding only when no model whose story
stiffnesses differ between the levels by at most JOINT_CHANGE (each story on its own, either
sign) fits both levels within the same price: the banded likelihood ratio of
:func:`banded_change` exceeds BIC's price of the held parameters.

JOINT_CHANGE = 3 %: the 1 % joints, as seen where an FRF is decided. An equivalent stiffness
3 k3 E[d^2] moves with the drift variance, and near a resonance the FRF is decided by the
Welch segments with the most drift: on 66 story draws (chirps and random drives) the
segment with the most drift carries 1.3-2.7 times the record's drift variance
(``research/joint_sizing.py``; docs/method/diagnosis.md), so 1 % joints look like up to
2.7 %, rounded up to 3 %. A planted stiffness nonlinearity the diagnosis is meant to find
(the catalogue's smallest, 0.06, changes its story by 7-8 % between the levels) lies above it.
"""

from dataclasses import replace

import numpy as np

from nlp.diagnosis.fitting import best_fit, continued, diagnosis_problem

JOINT_CHANGE = 0.03   # largest story stiffness change between levels that joints explain


def banded_change(ref, lv, limit, own, phi, delta=JOINT_CHANGE):
    """Can stiffness changes of at most ``delta`` per story carry the levels' difference?

    Each level's data are refitted with the masses held at the other level's optimum and
    each story stiffness free within +-delta (relative) of the other level's, damping free;
    the rise over the level's own fit is scaled by that fit's remaining misfit (as in
    :func:`nlp.diagnosis.levels.shared_stiffness`). Either way round is an upper bound of
    the likelihood ratio of the banded model, so the least is compared with ``limit``.
    own, phi: {"ref": .., "lv": ..}, each level's own chi-square and remaining misfit.

    Returns {"delta", "rises": {"other level": .., "reference": ..}, "excess", "limit",
    "converged", "material"}. Every rise, converged or not, bounds the banded likelihood
    ratio from above, so a least rise under the limit clears the level dependence; above it,
    the change is material only when that refit converged (as the level comparison itself
    asks of its shared fit).
    """
    rises = {}
    for key, (source, data, L) in {"other level": (ref, lv, "lv"),
                                   "reference": (lv, ref, "ref")}.items():
        res, pr = _banded_fit(source, data, delta)
        res = continued(pr, res)
        rises[key] = (max(float(2 * res.f) - own[L], 0.0) / phi[L], bool(res.success))
    at = min(rises, key=lambda k: rises[k][0])
    excess, ok = rises[at]
    return {"delta": float(delta), "rises": {k: v for k, (v, _) in rises.items()},
            "excess": excess, "limit": float(limit), "converged": ok, "way": at,
            "material": bool(excess > limit and ok)}


def band(theta_source, p, delta):
    """Bounds of a story's relative stiffness change (Eqn 23) within +-delta of the
    stiffness (1 + theta_source) k_nominal, inside the parameter's own bounds."""
    k = 1.0 + float(theta_source)
    lo, hi = max(k * (1.0 - delta) - 1.0, p.lower), min(k * (1.0 + delta) - 1.0, p.upper)
    return (lo, hi) if lo <= hi else (p.lower, p.upper)


def _banded_fit(source, data, delta):
    """``data``'s level fitted with masses held at ``source``'s optimum and stiffnesses
    within +-delta of it (damping free): (result, problem)."""
    pr_d, pr_s = data["problem"], source["problem"]
    sa, sb, _ = pr_d.params.slices()
    th_s = pr_s.theta(source["z"])
    th_d = pr_d.theta(data["z"])
    out = []
    for i, p in enumerate(pr_d.params.params):
        if p.fixed or not sa.start <= i < sb.stop:
            out.append(p)
        elif i < sa.stop:   # a story stiffness: free within the band
            lo, hi = band(th_s[i], p, delta)
            out.append(replace(p, lower=lo, upper=hi,
                               initial=float(np.clip(th_d[i], lo, hi))))
        else:               # a mass: held
            out.append(replace(p, fixed=True, initial=float(th_s[i])))
    params = replace(pr_d.params, params=tuple(out))
    c = data["case"]
    pr = diagnosis_problem(c, pr_d.target, optimize=False, damping=(c.damping, params))
    # starts: the data's own optimum brought into the band, and the source's stiffnesses
    start_own = np.array(th_d, float)
    start_src = np.array(th_d, float)
    for i in range(sa.start, sb.stop):
        p = params.params[i]
        start_own[i] = np.clip(th_d[i], p.lower, p.upper) if not p.fixed else p.initial
        start_src[i] = np.clip(th_s[i], p.lower, p.upper) if not p.fixed else p.initial
    return best_fit(pr, [params.z_from_theta(start_own), params.z_from_theta(start_src)]), pr
