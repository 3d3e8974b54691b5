"""What changes with the level on two-level lab cases: a story's stiffness, a floor's mass or
a story's damping (nlp.diagnosis.level_kind), against the generator's truth.

    python research/level_damping.py CASE [CASE ...]

CASE: a lab case folder with two levels (scripts/make_lab_benchmark.py, development seeds
only). Per case: whether the levels need masses and stiffnesses of their own
(levels.shared_stiffness), the best release of each kind (both ways round, drops summed), the
decision, whether the released parameter rises with the level, and the truth. One JSON line
per case goes to stderr. Beside them, the evidence a materiality rule could use: the modal
frequency shifts between the levels, the share of the levels' whole difference (both ways
round, every parameter held) that the best one-parameter release explains, and the
out-of-band harmonics (z of the power above the noise, the share of the best story), and the
pattern: a change of every story by one factor (the joints' signature) and the best story
released on top of it (one element's).
"""

import json
import os
import sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
sys.path.insert(0, ROOT)

from nlp.case.load import load_case  # noqa: E402
from nlp.diagnosis.level_kind import (CommonStiffness, _held, level_kind, level_order,  # noqa: E402
                                      release)
from nlp.diagnosis.levels import (_harmonics, _own_chi2, _phi, level_fit, level_location,  # noqa: E402
                                release_location, released_story, shared_stiffness)
from nlp.diagnosis.others import assemble_other  # noqa: E402


def pattern(ref, lv):
    """Drops (both ways round, scaled as level_kind's) of the common change, and of the best
    story released on top of it: the story's departure from the shared change."""
    phi_r, phi_l = _phi(ref), _phi(lv)
    held = _held(ref, lv) / phi_l + _held(lv, ref) / phi_r

    sa, _, _ = ref["problem"].params.slices()
    th_r, th_l = (f["problem"].theta(f["z"]) for f in (ref, lv))

    def drop(kind, i):
        co, vo, oko = release(ref, lv, kind, i, (CommonStiffness(),))
        cr, vr, okr = release(lv, ref, kind, i, (CommonStiffness(),))
        if kind == "stiffness":   # relative to the held level's theta, as level_kind
            vo, vr = vo - th_r[sa.start + i], vr - th_l[sa.start + i]
        return held - co / phi_l - cr / phi_r, 0.5 * (vo - vr), oko and okr

    g_drop, g, g_ok = drop(None, 0)
    rows = [drop("stiffness", i) + (i,) for i in range(ref["case"].model.n)]
    best = max(rows, key=lambda r: r[0])
    return {"common_drop": g_drop, "common_change": g, "common_converged": g_ok,
            "departure_story": best[3], "departure_drop": best[0] - g_drop,
            "departure_change": best[1],
            "departure_converged": best[2]}


def one(path):
    cfg = load_case(os.path.join(path, "case.yaml"))
    ref = level_fit(cfg, cfg.data.file)
    c, _ = assemble_other(cfg, cfg.data.level_files[0], lambda *a, **k: None)
    lv = level_fit(cfg, cfg.data.level_files[0], ref["z"], c)
    lr = shared_stiffness(ref, lv)
    kind = level_kind(ref, lv, _phi(ref), _phi(lv), level_order(ref, lv))
    with open(os.path.join(path, "truth.json")) as fh:
        truth = json.load(fh)
    what = truth.get("outside_effect") or truth.get("effects")
    harm = _harmonics(cfg, [ref, lv]) or {}
    score_story, _ = level_location(ref, lv)
    freed = released_story(release_location(ref, lv, lr))
    # the levels' difference: each level's data at the other's optimum above its own optimum
    total = (kind["held_chi2"]["other"] - _own_chi2(lv) / _phi(lv)
             + kind["held_chi2"]["reference"] - _own_chi2(ref) / _phi(ref))
    top = max(b["drop"] for b in kind["best"].values())
    pat = pattern(ref, lv)
    return {"case": os.path.basename(path), "truth": what,
            "location": truth.get("location") or [e["location"] for e in truth.get("effects", [])],
            "excess": lr["excess"], "limit": lr["limit"], "kind": kind,
            "shift_percent": [float(100 * (b / a - 1)) for a, b in zip(ref["f"], lv["f"])],
            "held_total": total, "best_share": top / total if total > 0 else float("nan"),
            "pattern": pat, "score_story": score_story, "freed_story": freed,
            "harmonics_z": harm.get("z_excess"), "harmonics_best": harm.get("story_index"),
            "harmonics_share": (max(harm["share"]) if harm.get("share") is not None
                                and len(harm["share"]) else None)}


def main():
    for path in sys.argv[1:]:
        r = one(path.rstrip("/"))
        k = r["kind"]
        best = "  ".join(f"{b['kind'][0]}{b['index'] + 1} {b['drop']:.0f} ({b['change']:+.3g})"
                         for b in sorted(k["best"].values(), key=lambda b: -b["drop"]))
        print(f"{r['case']:36s} excess {r['excess']:.0f}/{r['limit']:.0f}  {best}  -> "
              f"{k['kind']} {k['index'] + 1} (margin {k['margin']:.0f}, rises {k['rises']})  "
              f"truth {r['truth']} @ {r['location']}", flush=True)
        hz = r["harmonics_z"]
        print(f"{'':36s} shifts {', '.join(f'{x:+.2f}' for x in r['shift_percent'])} %; best "
              f"release explains {100 * r['best_share']:.0f} % of {r['held_total']:.0f}; "
              f"harmonics z {'-' if hz is None else f'{hz:.1f}'} (story "
              f"{r['harmonics_best'] if r['harmonics_best'] is None else r['harmonics_best'] + 1}, "
              f"share {r['harmonics_share']}); score test story {r['score_story'] + 1}, "
              f"freed story {r['freed_story'] if r['freed_story'] is None else r['freed_story'] + 1}",
              flush=True)
        p = r["pattern"]
        print(f"{'':36s} common change {100 * p['common_change']:+.2f} % explains "
              f"{100 * p['common_drop'] / r['held_total']:.0f} %; story {p['departure_story'] + 1} "
              f"on top of it ({100 * p['departure_change']:+.2f} %) drops {p['departure_drop']:.0f} more "
              f"(converged {p['common_converged']} {p['departure_converged']})", flush=True)
        print(json.dumps(r, default=str), file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
