"""Replay the damper rule on stored diagnoses of blind benchmarks, at several thresholds
of the excess's standard errors (priors.DAMPER_SE).

    python research/replay_damper_rule.py BENCH [BENCH ...] [--se 6 5 4 3] [--zeta 1.85 1.5 1.2]

Reads BENCH/*/diagnosis/diagnosis.json (its damping_decomposition) and truth.json. The
rule is that of priors.damper_check: the decomposition is judged (structured refit fits,
unexplained fraction under MAX_UNEXPLAINED), no pinned story next to the story, the excess
more than `se` standard errors from zero, the story's c/k one standard error low over
DAMPER_RATIO x the others' and its zeta ratio one standard error low over STORY_ZETA. The
lower ratio is recomputed from the stored values: rho = ref + excess / k_s, so
rho_lo / ref = 1 + (ratio - 1) (excess - se) / excess. Prints, per threshold, the stories
flagged at a true damper (right) and elsewhere (wrong). Diagnoses made by older code
carry that code's fits; the replay changes only the threshold.

``--zeta`` replays the zeta-ratio threshold (priors.STORY_ZETA) at the first ``--se``
instead, and closes with what it has to separate: the lower zeta ratio of each true
damper's story, by size, against the largest of every null or ordinary case's stories.
"""
import argparse
import glob
import json
import os

from nlp.diagnosis.priors import DAMPER_RATIO, MAX_UNEXPLAINED, STORY_ZETA


def flagged(dd, se_min, zeta=STORY_ZETA):
    """1-based stories the rule flags in one stored decomposition."""
    if not dd or "excess" not in dd or dd.get("unexplained_fraction", 0.0) >= MAX_UNEXPLAINED:
        return []
    if not dd.get("structured_refit", {}).get("fits", True):
        return []
    ex, se = dd["excess"], dd["excess_se"]
    ratio, zeta_lo = dd["ratio_to_others"], dd["story_zeta_ratio_lower"]
    pinned = [p - 1 for p in dd.get("pinned_stories", [])]
    out = []
    for s in range(len(ex)):
        if any(abs(p - s) <= 1 for p in pinned) or ex[s] <= 0 or ex[s] <= se_min * se[s]:
            continue
        ratio_lo = 1.0 + (ratio[s] - 1.0) * (ex[s] - se[s]) / ex[s]
        if ratio_lo > DAMPER_RATIO and zeta_lo[s] > zeta:
            out.append(s + 1)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bench", nargs="+")
    ap.add_argument("--se", type=float, nargs="+", default=[6.0, 5.0, 4.0, 3.0])
    ap.add_argument("--zeta", type=float, nargs="+", help="zeta-ratio thresholds to replay")
    a = ap.parse_args(argv)
    cases = []
    for b in a.bench:
        for p in sorted(glob.glob(os.path.join(b, "*", "diagnosis", "diagnosis.json"))):
            folder = os.path.dirname(os.path.dirname(p))
            with open(p) as fh:
                dd = json.load(fh).get("damping_decomposition")
            with open(os.path.join(folder, "truth.json")) as fh:
                truth = json.load(fh)
            dampers = {max(e["location"]["between"]): e["size"] for e in truth["effects"]
                       if e["family"] == "local_damper"}
            cases.append((f"{os.path.basename(b.rstrip('/'))}/{os.path.basename(folder)}",
                          dd, dampers, not truth["effects"]))
    print(f"{len(cases)} stored diagnoses")
    rules = [(a.se[0], z) for z in a.zeta] if a.zeta else [(t, STORY_ZETA) for t in a.se]
    for t, z in rules:
        right, wrong, null = [], [], 0
        for name, dd, dampers, is_null in cases:
            for s in flagged(dd, t, z):
                (right if s in dampers else wrong).append(f"{name} story {s}")
                null += is_null and s not in dampers
        print(f"excess > {t:g} SE, zeta ratio > {z:g}: right {len(right)}, wrong {len(wrong)} "
              f"({null} in null or ordinary cases)")
        if not a.zeta:
            for r in wrong:
                print(f"    wrong: {r}")
        print("    right: " + ", ".join(right))
    if a.zeta:
        judged = [(n, dd, d, u) for n, dd, d, u in cases if dd and "story_zeta_ratio_lower" in dd]
        print("lower zeta ratio of each true damper's story (size):")
        for name, dd, dampers, _ in judged:
            for s, size in sorted(dampers.items()):
                print(f"    {name} story {s} ({size:g}): {dd['story_zeta_ratio_lower'][s - 1]:.2f}")
        tail = sorted(max(dd["story_zeta_ratio_lower"]) for _, dd, _, u in judged if u)
        print(f"largest lower zeta ratio of each null or ordinary case ({len(tail)}): "
              + " ".join(f"{v:.2f}" for v in tail))


if __name__ == "__main__":
    main()
