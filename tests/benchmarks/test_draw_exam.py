"""scripts/draw_exam.py: exam seeds drawn after the freeze and written down before scoring."""

import os
import re
import subprocess
import sys

SCRIPT = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "draw_exam.py")


def _git(cwd, *args):
    return subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd,
                          capture_output=True, text=True, check=True).stdout.strip()


def _frozen_repo(tmp_path):
    for d in ("nlp/testing/lab", "nlp/testing/blind", "docs/benchmarks"):
        (tmp_path / d).mkdir(parents=True)
        (tmp_path / d / "x.py").write_text(d)
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", "-A")
    _git(tmp_path, "commit", "-qm", "freeze")
    return _git(tmp_path, "rev-parse", "HEAD")


def _draw(tmp_path, doc):
    return subprocess.run([sys.executable, os.path.abspath(SCRIPT), "--seeds", "3", "--doc", doc],
                          cwd=tmp_path, capture_output=True, text=True)


def test_the_draw_names_the_frozen_commit_and_three_exam_seeds(tmp_path):
    commit = _frozen_repo(tmp_path)
    p = _draw(tmp_path, "a.md")
    assert p.returncode == 0, p.stderr
    text = (tmp_path / "a.md").read_text()
    assert commit in text
    assert _git(tmp_path, "rev-parse", "HEAD:nlp/testing/lab") in text
    seeds = [int(s) for s in re.search(r"seeds: ([\d, ]+)", text).group(1).split(", ")]
    assert len(seeds) == 3 and all(s >= 100 for s in seeds)   # never a development seed
    assert all(f"--seed {s}" in text and f"seed_{s} --exam" in text for s in seeds)
    # from the entropy pool: a second draw gives other seeds (9e5^3 possible draws)
    (tmp_path / "a.md").unlink()
    p2 = _draw(tmp_path, "b.md")
    seeds2 = re.search(r"seeds: ([\d, ]+)", (tmp_path / "b.md").read_text()).group(1)
    assert p2.returncode == 0 and seeds2 != ", ".join(map(str, seeds))


def test_an_unfrozen_tree_is_refused_and_nothing_is_written(tmp_path):
    _frozen_repo(tmp_path)
    (tmp_path / "nlp/testing/lab/x.py").write_text("changed after the freeze")
    p = _draw(tmp_path, "a.md")
    assert p.returncode == 2 and "uncommitted" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "a.md").exists()
