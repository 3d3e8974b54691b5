"""Where to draw the line between a concentrated damper and non-proportional damping.

Draws real structures as the blind generator does (scripts/make_blind_benchmark.py:
Rayleigh damping plus 40 % of C as story dashpots of random Dirichlet shares), with and
without a local damper of size 1, 2, 4 (c / (2 zeta sqrt(k m)) of its story), and prints,
on the true matrices (no estimation error), how often each rule flags the right story
(null draws: any story). Run: python research/damper_threshold.py [--draws N] [--seed S]
"""

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from nlp.testing.blind import structures as mb  # noqa: E402
from nlp.diagnosis.priors import (DAMPER_RATIO, STORY_ZETA, _excess, modal_share,  # noqa: E402
                                  story_damping_ratio)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=2)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    sizes = [0.0, 1.0, 2.0, 4.0]
    rules = {
        f"story damping ratio > {STORY_ZETA} x median modal without it, c/k > {DAMPER_RATIO} x others":
            lambda r, z, z_in, sh: (z > STORY_ZETA) & (r > DAMPER_RATIO),
        f"story damping ratio > 1.35 x median modal with it in, c/k > {DAMPER_RATIO} x (before)":
            lambda r, z, z_in, sh: (z_in > 1.35) & (r > DAMPER_RATIO),
        "modal share > 0.6, c/k > 3 x others (the rule before that)":
            lambda r, z, z_in, sh: (sh > 0.6) & (r > 3.0),
    }
    hits = {k: {s: [] for s in sizes} for k in rules}
    for t in range(a.draws):
        n = int(rng.integers(3, 6))
        st = mb.real_structure(rng, n, t % 2 == 0)
        size = sizes[t % len(sizes)]
        C, loc = st["C"].copy(), None
        if size:
            loc = int(rng.integers(1, n + 1))
            C = mb.with_effect(st, (st["M"], st["C"], st["K"], np.zeros((n, n))), "local_damper",
                               (loc, loc - 1), size, rng)[1]
        ex, rho, ref, _ = _excess(C, st["M"], st["K"])
        ratio = rho / ref
        zeta = story_damping_ratio(st["M"], st["K"], C, ex)[0]
        zeta_in = story_damping_ratio(st["M"], st["K"], C, ex, removed=np.zeros(n))[0]
        share = modal_share(st["M"], st["K"], C, ex).max(axis=1)
        for name, rule in rules.items():
            flag = rule(ratio, zeta, zeta_in, share)
            for key in (name, (name, n)):
                hits.setdefault(key, {s: [] for s in sizes})[size].append(
                    bool(flag.any()) if loc is None else bool(flag[loc - 1]))
    print(f"{a.draws} draws, seed {a.seed}: share of draws flagged (null: any story; "
          "damper: its story)")
    print(f"{'rule':80s} " + " ".join(f"{'null' if s == 0 else f'size {s:g}':>8s}" for s in sizes))
    for name in rules:
        for key, label in [(name, name)] + [((name, n), f"  {n} storeys") for n in (3, 4, 5)]:
            print(f"{label:80s} " + " ".join(f"{np.mean(hits[key][s]):8.3f}" for s in sizes))


if __name__ == "__main__":
    main()
