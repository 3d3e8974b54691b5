"""Figures of a lab exam scored so far, pooled over its seeds (issue 48).

    python scripts/exam_progress.py --order docs/benchmarks/exam_20261128T025926Z_order.txt \
        [--root /work/exam/exam_20261128T025926Z] \
        [--scores docs/benchmarks/exam_20261128T025926Z_scores.jsonl] [--write FILE] [--table]

The exam's cases are scored in the random order drawn before the first was scored (one
``seed case`` per line of --order); ROOT/seed_S/scores.jsonl hold the results
(scripts/score_lab.py), and --scores a copy of them kept in the repository (one row per
case, with its seed), since a session's machine does not outlive it. --write writes every
row read to FILE (that copy), in the drawn order; --table prints the scored prefix as the
exam page's markdown table. Any prefix of the order is a uniform sample of the exam, so the
figures are those of the longest scored prefix; cases scored beyond it are counted apart.
"""

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from score_lab import summary  # noqa: E402  (the same figures as one seed's scoring)


def _time(r):
    """'347 s', '1800 s (timeout)' or '319 s (exit 2: ...)'."""
    t = f"{r['seconds']:.0f} s"
    if r["exit"] == 0:
        return t
    return t + (" (timeout)" if r["exit"] == "timeout" else
                f" (exit {r['exit']}: {' '.join(r['error'])[:120]})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", required=True)
    ap.add_argument("--root")
    ap.add_argument("--scores")
    ap.add_argument("--write")
    ap.add_argument("--table", action="store_true")
    a = ap.parse_args()
    with open(a.order) as fh:
        order = [ln.split() for ln in fh if ln.strip()]
    scored = {}
    if a.scores and os.path.isfile(a.scores):
        with open(a.scores) as fh:
            for r in map(json.loads, filter(str.strip, fh)):
                scored[str(r["seed"]), r["case"][:2]] = r
    for seed in {s for s, _ in order} if a.root else ():
        log = os.path.join(a.root, f"seed_{seed}", "scores.jsonl")
        if os.path.isfile(log):
            with open(log) as fh:
                for r in map(json.loads, filter(str.strip, fh)):
                    scored[seed, r["case"][:2]] = {"seed": int(seed), **r}
    if a.write:
        rows = [scored[tuple(k)] for k in order if tuple(k) in scored]
        tmp = a.write + ".tmp"
        with open(tmp, "w") as fh:
            fh.writelines(json.dumps(r) + "\n" for r in rows)
        os.replace(tmp, a.write)
    prefix = []
    for key in map(tuple, order):
        if key not in scored:
            break
        prefix.append(scored[key])
    beyond = len(scored) - len(prefix)
    print(f"scored {len(scored)} of {len(order)} exam cases; the longest scored prefix of the "
          f"drawn order holds {len(prefix)}" + (f" ({beyond} more scored beyond it, not counted)"
                                                if beyond else ""))
    if prefix:
        summary(prefix)
    if a.table:
        print("\n| # | seed | case | verdict | judged | time | findings |\n|---|---|---|---|---|---|---|")
        for k, r in enumerate(prefix, 1):
            print(f"| {k} | {r['seed']} | {r['case']} | {r['label']} | "
                  f"{'right' if r['ok'] else 'wrong'} | {_time(r)} | "
                  f"{'; '.join(r['found']) or '-'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
