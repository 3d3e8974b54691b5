"""Instructions per local solve of the four-storey case, counted by callgrind (issue 47).

    python research/solve_instructions.py [--solves 30]

Wall time on a shared machine moves with the load; instruction counts do not. The case is
built and N local solves run (the starts of scripts/bench_core.py) under
`valgrind --tool=callgrind`, once with the solves and once without, and the difference over
N is printed. Run it in two checkouts to compare code versions (docs/benchmarks/results.md).
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
CHILD = """
import os, sys
sys.path.insert(0, os.path.join({root!r}, "scripts"))
from bench_core import DEFAULT_CASE, build_timed, start_points
_, problem, _, _ = build_timed(os.path.join({root!r}, DEFAULT_CASE), {{}})
for z in start_points(problem, {n}, 0)[:{k}]:
    problem.solve(z)
"""


def instructions(root, n, k):
    """Instructions callgrind collects for the build and k of n solves."""
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp}/cg",
                              sys.executable, "-c", CHILD.format(root=root, n=n, k=k)],
                             capture_output=True, text=True, cwd=root,
                             env={**os.environ, "PYTHONPATH": root})
    m = re.search(r"Collected : (\d+)", out.stderr)
    if not m:
        raise SystemExit(f"callgrind gave no count:\n{out.stderr[-2000:]}")
    return int(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solves", type=int, default=30)
    a = ap.parse_args()
    root = os.path.dirname(HERE)
    base = instructions(root, a.solves, 0)
    full = instructions(root, a.solves, a.solves)
    print(f"{root}: {(full - base) / a.solves / 1e6:.1f} million instructions per local solve "
          f"({a.solves} solves; build {base / 1e9:.2f} G)")


if __name__ == "__main__":
    main()
