"""Draw the seeds of a lab exam after the freeze and write them down before any scoring (issue 48).

    python scripts/draw_exam.py --seeds 3 [--cases 40] [--timeout 2400] [--budget 25]
        [--doc docs/benchmarks/exam_<stamp>.md]

The code and the generator are frozen at the current commit (the work tree must be clean).
Each seed is 100 + a number read from the operating system's entropy pool (os.urandom) at the
moment of the draw, so nobody knows it at freeze time; seeds 0-99 are development seeds
(scripts/score_lab.py refuses exam seeds without --exam). The file written names the commit,
the generator's tree (git tree hashes of nlp/testing/lab and nlp/testing/blind), the seeds,
the time of the draw and the commands that generate and score the exam, and beside it
exam_<stamp>_order.txt: every ``seed case`` in a random order drawn from the same pool, the
order in which the cases are scored, so that any prefix is a uniform sample of the exam (a
session ends its jobs; the exam is scored over several). Commit both before scoring; score
each seed once; the cases are never development data.
"""

import argparse
import datetime
import os
import subprocess
import sys

SEED_SPAN = 900_000   # exam seeds are 100 .. 900,099


def git(*args):
    return subprocess.run(["git", *args], capture_output=True, text=True, check=True).stdout.strip()


def _order_path(doc):
    return doc[:-3] + "_order.txt" if doc.endswith(".md") else doc + "_order.txt"


def _write_order(path, seeds, cases):
    """Every (seed, case) in a random order from the entropy pool (Fisher-Yates)."""
    pairs = [(s, k) for s in seeds for k in range(cases)]
    for i in range(len(pairs) - 1, 0, -1):
        j = int.from_bytes(os.urandom(8), "big") % (i + 1)
        pairs[i], pairs[j] = pairs[j], pairs[i]
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("".join(f"{s} {k:02d}\n" for s, k in pairs))
    os.replace(tmp, path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cases", type=int, default=40, help="cases per seed (make_lab_benchmark)")
    ap.add_argument("--timeout", type=float, default=2400.0, help="seconds a case may take")
    ap.add_argument("--budget", type=float, default=25.0, help="diagnose --budget [min]")
    ap.add_argument("--doc", default=None, help="file to write (default docs/benchmarks/exam_<UTC stamp>.md)")
    a = ap.parse_args()
    if a.seeds < 1:
        print("draw_exam.py: --seeds: expected a positive count", file=sys.stderr)
        return 2
    if git("status", "--porcelain", "--untracked-files=no"):
        print("draw_exam.py: the work tree has uncommitted changes: commit them first (the "
              "exam is of a frozen commit)", file=sys.stderr)
        return 2
    now = datetime.datetime.now(datetime.timezone.utc)
    stamp = now.strftime("%Y%m%dT%H%M%SZ")
    seeds = [100 + int.from_bytes(os.urandom(8), "big") % SEED_SPAN for _ in range(a.seeds)]
    commit = git("rev-parse", "HEAD")
    trees = {p: git("rev-parse", f"HEAD:{p}") for p in ("nlp/testing/lab", "nlp/testing/blind")}
    doc = a.doc or os.path.join("docs", "benchmarks", f"exam_{stamp}.md")
    folder = f"exam_{stamp}"
    lines = [f"# Lab exam drawn {now.isoformat(timespec='seconds')}",
             "",
             "Written by `scripts/draw_exam.py` after the freeze and before any case was generated",
             "or scored (issue 48). The seeds come from the operating system's entropy pool at the",
             "time of the draw. Each seed is scored once; its cases are never development data.",
             "",
             f"- frozen commit: `{commit}`",
             *[f"- generator tree `{p}`: `{h}`" for p, h in trees.items()],
             f"- seeds: {', '.join(str(s) for s in seeds)}",
             "",
             "Generate and score (one case at a time, each diagnosed by the frozen commit):",
             "",
             *[f"    python scripts/make_lab_benchmark.py --out {folder}/seed_{s} --seed {s}"
               for s in seeds],
             *[f"    python scripts/score_lab.py --bench {folder}/seed_{s} --exam "
               f"--timeout {a.timeout:g} --budget {a.budget:g} --only CASE"
               for s in seeds],
             "",
             f"one case at a time, in the order of `{os.path.basename(_order_path(doc))}`.",
             ""]
    _write_order(_order_path(doc), seeds, a.cases)
    tmp = doc + ".tmp"
    with open(tmp, "w") as fh:
        fh.write("\n".join(lines))
    os.replace(tmp, doc)
    print(doc)
    print(" ".join(str(s) for s in seeds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
