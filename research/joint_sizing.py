"""How large are the lab's joints where an FRF looks at them?

The lab sizes each story's cubic joint on the whole record's drift variance (links.joints:
3 k3 E[d^2] changes by 0.5-1 % of k between level 1 and 3x level 1). An FRF at a resonance
sees the drift while the drive is at that frequency: for a random drive that is the whole
record's variance, for a chirp it is the short passage through the resonance, where the
drift is far above its record RMS. This prints, per story of the nulls of a development
seed, the drift variance of the Welch segment with the largest variance over the record's
variance, and the equivalent-stiffness change between levels that the segment implies
(the sized change times that ratio, statistical linearisation on the segment).

    python research/joint_sizing.py --seeds 7 8

The generator's random draws are replayed (make_case's order) without writing records.
"""

import argparse

import numpy as np

from nlp.testing.blind.cases import describe_test
from nlp.testing.blind.experiment import SIM_FACTOR, drive
from nlp.testing.lab.cases import column_names, draw_lab, plant, specs, structure
from nlp.testing.lab.experiment import simulate
from nlp.testing.lab.links import active, drift


def segment_ratio(d, n_seg):
    """Largest variance of a half-overlapping segment of n_seg samples over the record's."""
    step = n_seg // 2
    var = [np.var(d[i:i + n_seg]) for i in range(0, len(d) - n_seg + 1, step)]
    return max(var) / np.var(d)


def null_rows(seed, k, spec):
    rng = np.random.default_rng(seed * 1000 + k)
    st = structure(rng, spec)
    test = describe_test(rng, spec, st)
    lab = draw_lab(rng, test, st, column_names(test))
    test["seconds"] = 200.0
    t, u = drive(test, seed * 1000 + k + 7)
    sysm, _, _, _ = plant(rng, spec, st, test, lab, u)
    q1 = simulate({**sysm, "links": []}, lab, test, u, 1.0)[1]
    n_seg = 4096 * SIM_FACTOR   # the case files' Welch segment, at the simulation rate
    rows = []
    for lk in sysm["links"]:
        if lk.get("kind") != "cubic" or "change_1_to_3" not in lk:
            continue
        d = active(drift(q1, lk["story"], test.get("base_dof")), u)
        r = segment_ratio(d, n_seg)
        rows.append((lk["story"], lk["change_1_to_3"], r, lk["change_1_to_3"] * r))
    return test, rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", required=True)
    a = ap.parse_args()
    print("seed/case  signal  levels  story  sized change  segment var / record var  change on that segment")
    for seed in a.seeds:
        for k, spec in enumerate(specs(np.random.default_rng(seed))):
            if spec["category"] != "null_lab":
                continue
            test, rows = null_rows(seed, k, spec)
            lv = 2 if spec.get("two_levels") else 1
            for s, ch, r, eff in rows:
                print(f"{seed}/{k:02d}      {spec['signal']:6s}  {lv}       {s}      {100 * ch:+.2f} %"
                      f"       {r:6.1f}                    {100 * eff:+.1f} %", flush=True)


if __name__ == "__main__":
    main()
